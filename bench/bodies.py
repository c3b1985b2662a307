"""Both strategies on every catalogue body, as the tables of docs/benchmarks.md
("Bodies"): the sweeps run through ``sensorispace sweep`` (Dask), this reads
their ``summary.json`` and prints one Markdown row per body.

    sensorispace sweep --strategy paper --config config/bodies/*.yaml --seeds 0-2 \\
        --out results/bodies-paper
    sensorispace sweep --strategy naive --config config/bodies/*.yaml --seeds 0-2 \\
        --out results/bodies-naive
    .venv/bin/python -m bench.bodies results/bodies-paper results/bodies-naive

Ranges are min-max over the seeds (one number when they agree).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path


def _range(metrics: dict, key: str, digits: str = "g") -> str:
    entry = metrics.get(key)
    if entry is None:
        return "–"
    low, high = (format(entry[side], digits) for side in ("min", "max"))
    return low if low == high else f"{low}–{high}"


def paper_rows(summary: dict) -> list[str]:
    rows = ["| body | seeds | compensated + split | compensable | 2-D after affine residual "
            "| trustworthiness | wall time (s) |", "|---|---|---|---|---|---|---|"]
    for name, config in sorted(summary["configs"].items()):
        m = config["metrics"]
        followed = {side: m["exploration.compensated"][side]
                    + m.get("exploration.failures.split_point_of_view", {side: 0})[side]
                    for side in ("min", "max")}
        followed = (f"{followed['min']:g}" if followed["min"] == followed["max"]
                    else f"{followed['min']:g}–{followed['max']:g}")
        rows.append(f"| {name} | {len(config['seeds'])} | {followed} "
                    f"| {_range(m, 'body.compensable_positions')} "
                    f"| {_range(m, 'quality.2d.after.affine_residual', '.1e')} "
                    f"| {_range(m, 'quality.2d.after.trustworthiness', '.5f')} "
                    f"| {_range(m, 'timings_s.total', '.0f')} |")
    return rows


def naive_rows(summary: dict) -> list[str]:
    rows = ["| body | pose rank (true / found) | POV dim (true / found) | rank gap | space dim "
            "| POVs | coverage | wrong poses | state changes accepted "
            "| 2-D after affine residual | trustworthiness | calls per POV | wall time (s) |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, config in sorted(summary["configs"].items()):
        m = config["metrics"]
        calls = {side: m["naive.calls_total"][side] / max(m["pov.count"][side], 1)
                 for side in ("min", "max")} if "naive.calls_total" in m else None
        calls = "–" if calls is None else f"{calls['min']:.0f}–{calls['max']:.0f}"
        rows.append(
            f"| {name} | {_range(m, 'body.pose_rank')} / {_range(m, 'naive.pose_rank')} "
            f"| {_range(m, 'body.pov_dim')} / {_range(m, 'naive.pov_dim')} "
            f"| {_range(m, 'naive.rank_gap', '.2g')} | {_range(m, 'naive.space_dim')} "
            f"| {_range(m, 'pov.count')} | {_range(m, 'naive.coverage', '.3f')} "
            f"| {_range(m, 'naive.wrong_poses')} | {_range(m, 'naive.state_changes_accepted')} "
            f"| {_range(m, 'quality.2d.after.affine_residual', '.1e')} "
            f"| {_range(m, 'quality.2d.after.trustworthiness', '.5f')} | {calls} "
            f"| {_range(m, 'timings_s.total', '.0f')} |")
    return rows


def main(paper_dir: str, naive_dir: str) -> None:
    for title, directory, rows in (("paper strategy", paper_dir, paper_rows),
                                   ("naive strategy", naive_dir, naive_rows)):
        path = Path(directory) / "summary.json"
        if not path.is_file():
            print(f"{path}: no sweep summary", file=sys.stderr)
            continue
        print(f"\n{title} ({path.parent})\n")
        print("\n".join(rows(json.loads(path.read_text()))))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit("usage: python -m bench.bodies PAPER_SWEEP_DIR NAIVE_SWEEP_DIR")
    main(sys.argv[1], sys.argv[2])
