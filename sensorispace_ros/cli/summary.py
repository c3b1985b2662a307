"""How the ``sensorispace`` verbs print numbers and a run's summary table."""
from __future__ import annotations

import math
from functools import partial
from pathlib import Path

from sensorispace_ros.evaluation.run_files import metric


def fmt(value, digits: int = 4) -> str:
    """A metric value in a few characters: ints as they are, floats to ``digits``
    significant digits (scientific when tiny or huge), long lists as their ends."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value == 0.0:
            return "0"
        if not math.isfinite(value):
            return str(value)
        if abs(value) < 1e-3 or abs(value) >= 1e5:
            return f"{value:.{digits - 1}e}"
        if abs(value) < 1:
            return f"{value:.{digits}g}"
        return f"{value:.{digits}f}".rstrip("0").rstrip(".")
    if isinstance(value, list):
        if len(value) <= 3:
            return "[" + ", ".join(fmt(v, 3) for v in value) + "]"
        return f"[{fmt(value[0], 3)} .. {fmt(value[-1], 3)}] ({len(value)})"
    return str(value)


def summary_table(metrics: dict, out: Path | None = None) -> str:
    """A short human summary of one run's metrics.json."""
    get = partial(metric, metrics)
    head = f"{metrics.get('strategy', '?')} strategy, seed {metrics.get('seed', '?')}"
    lines = [head + (f" -> {out}" if out is not None else "")]
    if "outcome" in metrics:
        lines.append(f"  {metrics['outcome']}")
    lines.append(f"  exploration: {fmt(get('exploration.events'))} events, "
                 f"{fmt(get('exploration.state_changes'))} state changes, "
                 f"{fmt(get('exploration.compensated'))} compensated, "
                 f"{fmt(get('exploration.state_changes_compensated'))} state changes compensated")
    lines.append(f"  points of view: {fmt(get('pov.count'))}, "
                 f"max pose drift {fmt(get('pov.max_pose_drift'))}; "
                 f"equality sets: {fmt(get('equality_sets.count'))} "
                 f"({fmt(get('equality_sets.pairs'))} changes)")
    naive = get("naive")
    if isinstance(naive, dict) and naive:
        lines.append("  naive: " + ", ".join(f"{k} {fmt(v)}" for k, v in sorted(naive.items())
                                             if not isinstance(v, (dict, list))))
    lines += _quality_rows(get)
    lines.append(_timings_row(get("timings_s") or {}))
    return "\n".join(lines)


def _quality_rows(get) -> list[str]:
    columns = ("trustworthiness", "continuity", "spearman", "affine_residual")
    rows = [f"  {'':12}" + "".join(f"{c:>17}" for c in columns) + f"{'reach straightness':>20}"]
    for dim in ("2d", "3d"):
        for stage in ("before", "after"):
            row = f"  {dim.upper() + ' ' + stage:12}"
            row += "".join(f"{fmt(get(f'quality.{dim}.{stage}.{c}')):>17}" for c in columns)
            row += f"{fmt(get(f'reaching.{dim}.{stage}.straightness_median')):>20}"
            rows.append(row)
    rows.append(f"  {'Hausdorff':12}" + " " * (17 * len(columns))
                + f"{fmt(get('reaching.hausdorff.straightness_median')):>20}")
    return rows


def _timings_row(timings: dict) -> str:
    order = ("exploration", "points_of_view", "equality_sets", "hausdorff", "cca",
             "regularization", "reaching", "total", "figures")
    shown = [k for k in order if k in timings] + sorted(set(timings) - set(order))
    return "  time (s): " + ", ".join(f"{k} {fmt(timings[k], 3)}" for k in shown)
