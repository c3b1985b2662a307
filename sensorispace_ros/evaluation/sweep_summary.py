"""The spread of every result over a sweep's seeds: ``summary.json`` and ``summary.md``.

Per configuration and per numeric metric (timings included, configuration
echo and identifiers excluded): mean, standard deviation (population, ``ddof=0``),
min, max, and the seeds where the min and the max were reached (the lowest
seed on ties).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from sensorispace_ros.evaluation.run_files import METRICS_FILE, flatten_metrics

SUMMARY_JSON = "summary.json"
SUMMARY_MD = "summary.md"
# Keys that identify a run or echo its input rather than measure it.
NOT_RESULTS = ("config.", "seed", "strategy")


def _is_result(key: str, value) -> bool:
    if any(key == k or key.startswith(k) for k in NOT_RESULTS):
        return False
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return math.isfinite(value)


def run_metrics(run_dirs: dict[int, Path]) -> dict[int, dict]:
    """``{seed: flat metrics}`` of the complete runs among ``run_dirs``."""
    out = {}
    for seed, run_dir in sorted(run_dirs.items()):
        path = Path(run_dir) / METRICS_FILE
        if path.is_file():
            out[seed] = flatten_metrics(json.loads(path.read_text()))
    return out


def spread(by_seed: dict[int, dict]) -> dict[str, dict]:
    """Per metric key: ``{mean, sd, min, max, seed_min, seed_max, runs}``."""
    keys = sorted({k for flat in by_seed.values() for k, v in flat.items() if _is_result(k, v)})
    table = {}
    for key in keys:
        pairs = [(seed, float(flat[key])) for seed, flat in sorted(by_seed.items())
                 if key in flat and _is_result(key, flat[key])]
        seeds = [s for s, _ in pairs]
        values = np.asarray([v for _, v in pairs])
        table[key] = {"mean": float(values.mean()), "sd": float(values.std()),
                      "min": float(values.min()), "max": float(values.max()),
                      "seed_min": seeds[int(np.argmin(values))],
                      "seed_max": seeds[int(np.argmax(values))], "runs": len(values)}
    return table


def summarize(sweep_dir: str | Path, runs: dict[str, dict[int, Path]], strategy: str) -> dict:
    """Write ``summary.json`` and ``summary.md`` for ``runs`` (per config name, per seed)."""
    sweep_dir = Path(sweep_dir)
    summary = {"strategy": strategy, "configs": {}}
    for name, run_dirs in sorted(runs.items()):
        by_seed = run_metrics(run_dirs)
        summary["configs"][name] = {"seeds": sorted(by_seed), "metrics": spread(by_seed)}
    sweep_dir.mkdir(parents=True, exist_ok=True)
    (sweep_dir / SUMMARY_JSON).write_text(json.dumps(summary, indent=1, sort_keys=True) + "\n")
    (sweep_dir / SUMMARY_MD).write_text(summary_markdown(summary))
    return summary


def _number(value: float) -> str:
    if value == 0 or 1e-3 <= abs(value) < 1e5:
        return f"{value:.6g}"
    return f"{value:.3e}"


def _seed_list(seeds: list[int]) -> str:
    """``[0, 1, 2, 5]`` as ``0-2, 5``."""
    parts, start = [], None
    for i, seed in enumerate(seeds):
        if start is None:
            start = seed
        if i + 1 == len(seeds) or seeds[i + 1] != seed + 1:
            parts.append(str(start) if start == seed else f"{start}-{seed}")
            start = None
    return ", ".join(parts)


# Metrics whose name alone misleads, explained under the table that shows them.
METRIC_NOTES = {
    "naive.coverage_of_paper_positions":
        "the fraction of the paper strategy's very sensor positions the naive agent reaches, "
        "beside its coverage (`naive.coverage`, distinct positions over the paper strategy's "
        "count): equal when the agent's positions are the paper strategy's",
}


def summary_markdown(summary: dict) -> str:
    """One table per configuration: metric, mean, sd, min (seed), max (seed); then
    the notes (``METRIC_NOTES``) of the metrics it shows."""
    lines = [f"# Sweep summary: strategy `{summary['strategy']}`", ""]
    for name, entry in summary["configs"].items():
        lines += [f"## `{name}`: seeds {_seed_list(entry['seeds'])} ({len(entry['seeds'])} runs)",
                  "", "| metric | mean | sd | min (seed) | max (seed) |",
                  "|---|---|---|---|---|"]
        for key, s in entry["metrics"].items():
            lines.append(f"| `{key}` | {_number(s['mean'])} | {_number(s['sd'])} | "
                         f"{_number(s['min'])} ({s['seed_min']}) | "
                         f"{_number(s['max'])} ({s['seed_max']}) |")
        lines.append("")
        lines += [f"`{key}`: {note}." for key, note in METRIC_NOTES.items()
                  if key in entry["metrics"]]
        lines += [""] * any(key in entry["metrics"] for key in METRIC_NOTES)
    return "\n".join(lines)
