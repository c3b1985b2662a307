"""A run directory: ``metrics.json``, ``arrays.npz`` and ``figures/*.png``.

``run_arrays`` names what a run keeps to redraw its figures or be evaluated
again (``representation_from_arrays`` reads the representation back);
``write_metrics`` / ``read_metrics`` the metrics file, floats rounded to
``FLOAT_DIGITS`` significant digits (``runs.write_run`` writes the three).
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.offline.pov_assembly import embedding_arrays
from sensorispace_ros.offline.representation import DIMENSIONS, Representation

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sensorispace_ros.offline.strategies import StrategyOutput

METRICS_FILE = "metrics.json"
ARRAYS_FILE = "arrays.npz"
FIGURES_DIR = "figures"
# Significant digits written to metrics.json: far below every acceptance bar,
# and it keeps last-bit noise of BLAS reductions out of run-to-run diffs.
FLOAT_DIGITS = 12


def run_arrays(produced: StrategyOutput, representation: Representation, cfg: dict,
               seed: int) -> dict:
    """Everything needed to redraw the figures or re-evaluate, as arrays."""
    arrays = {
        "povs": np.asarray(produced.povs),
        "true_positions": np.asarray(produced.true_positions),
        "pairs": np.asarray(produced.pairs),
        "set_ids": np.asarray(produced.set_ids),
        "hausdorff": representation.distance,
        "config_json": np.asarray(json.dumps(cfg, sort_keys=True)),
        "seed": np.int64(seed),
    }
    return {**arrays, **embedding_arrays(representation)}


def representation_from_arrays(arrays) -> Representation:
    """The ``Representation`` stored in a run's arrays (``run_arrays`` names)."""
    timings = {}
    if "timings_s_json" in arrays:
        timings = json.loads(str(np.asarray(arrays["timings_s_json"])))
    dims = [key[len("embedding_"):-len("_before")] for key in arrays
            if key.startswith("embedding_") and key.endswith("_before")]
    dims = sorted(dims, key=lambda dim: (dim not in DIMENSIONS, dim))
    return Representation(
        distance=np.asarray(arrays["hausdorff"]),
        before={dim: np.asarray(arrays[f"embedding_{dim}_before"]) for dim in dims},
        iterations={dim: np.asarray(arrays[f"embedding_{dim}_iterations"]) for dim in dims},
        set_spread={dim: np.asarray(arrays[f"set_spread_{dim}"]) for dim in dims},
        timings_s=timings)


def nest(flat: dict) -> dict:
    """Dotted keys -> nested dicts (``"a.b": 1`` -> ``{"a": {"b": 1}}``)."""
    out: dict = {}
    for key, value in flat.items():
        node = out
        parts = key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ValueError(f"metric {key!r} collides with a value at {part!r}")
        if isinstance(node.get(parts[-1]), dict):
            raise ValueError(f"metric {key!r} collides with a group of metrics")
        node[parts[-1]] = value
    return out


def flatten_metrics(metrics: dict, prefix: str = "") -> dict:
    """Nested metrics -> dotted keys (the same rule as the config's parameter names)."""
    return config_mod.flatten(metrics, prefix)


def metric(metrics: dict, dotted: str, default=None):
    """The value at a dotted key of nested metrics (``"pov.count"``), or ``default``."""
    node = metrics
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node


def as_written(value):
    """``value`` as ``write_metrics`` writes it: plain JSON types, floats
    rounded to ``FLOAT_DIGITS`` significant digits, non-finite ones None."""
    if isinstance(value, dict):
        return {str(k): as_written(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [as_written(v) for v in np.asarray(value, dtype=object).tolist()] \
            if isinstance(value, np.ndarray) else [as_written(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if not math.isfinite(value):
            return None                   # JSON has no NaN / inf
        return float(f"{value:.{FLOAT_DIGITS}g}")
    return value


def write_metrics(metrics: dict, path: str | Path) -> None:
    """Sorted keys, floats rounded to ``FLOAT_DIGITS`` significant digits."""
    path = Path(path)
    text = json.dumps(as_written(metrics), sort_keys=True, indent=2) + "\n"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def read_metrics(path: str | Path) -> dict:
    """metrics.json of a run directory (or the file itself)."""
    path = Path(path)
    if path.is_dir():
        path = path / METRICS_FILE
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such metrics file") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
