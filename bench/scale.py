"""Cost of every stage vs the number of points of view.

Runs ``sensorispace reproduce --strategy paper`` (figures off: they are not a
stage of the science) in a child process per grid size, each from
config/paper.yaml with only ``world.grid_count`` changed (the 124 grid is
config/paper-124.yaml itself), reads the stage timings from its
metrics.json, the child's peak RSS from ``os.wait4``, and fits
t = c * P**k per stage by least squares in log-log.
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

if str(Path(__file__).resolve().parent.parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.child import REPO, load, reproduce_command, run_measured

STAGES = ("exploration", "points_of_view", "equality_sets", "hausdorff", "cca",
          "regularization", "reaching", "total")


def grid_config(grid_count: int, directory: Path) -> Path:
    """config/paper-124.yaml for 124, else paper.yaml with ``world.grid_count`` set."""
    if grid_count == 124:
        return REPO / "config" / "paper-124.yaml"
    document = yaml.safe_load((REPO / "config" / "paper.yaml").read_text())
    document["/**"]["ros__parameters"]["world"]["grid_count"] = int(grid_count)
    path = directory / f"paper-{grid_count}.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


def fit_exponent(counts, seconds) -> float | None:
    """k of t = c * P**k (least squares on logs); None with < 2 usable points."""
    counts, seconds = np.asarray(counts, float), np.asarray(seconds, float)
    ok = (counts > 0) & (seconds > 0)
    if ok.sum() < 2:
        return None
    return float(np.polyfit(np.log(counts[ok]), np.log(seconds[ok]), 1)[0])


def run_scale(grid_counts=(32, 62, 124), out_root: str | Path | None = None,
              timeout_s: float = 1800.0, existing: dict | None = None) -> dict:
    """One measured run per grid size; ``existing`` maps a grid size to an
    already measured run (``{"run": run_measured(...), "metrics": {...}}``)."""
    existing = existing or {}
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        root = Path(out_root) if out_root else tmp
        for n in grid_counts:
            if n in existing:
                runs[n] = existing[n]
                continue
            out_dir = root / f"scale-{n}"
            measured = run_measured(reproduce_command(grid_config(n, tmp), "paper", out_dir,
                                                      figures=False),
                                    root / f"scale-{n}.log", timeout_s=timeout_s)
            metrics = json.loads((out_dir / "metrics.json").read_text()) \
                if measured["exit_code"] == 0 else {}
            runs[n] = {"run": measured, "metrics": metrics}
    table = {}
    for n, entry in runs.items():
        metrics = entry["metrics"]
        table[str(n)] = {
            "grid_count": n,
            "povs": metrics.get("pov", {}).get("count"),
            "stages_s": {s: metrics.get("timings_s", {}).get(s) for s in STAGES},
            "wall_s": entry["run"]["wall_s"], "peak_rss_mib": entry["run"]["peak_rss_mib"],
            "exit_code": entry["run"]["exit_code"],
            "load_before": entry["run"]["load_before"], "load_after": entry["run"]["load_after"],
        }
    done = [row for row in table.values() if row["povs"]]
    exponents = {s: fit_exponent([r["povs"] for r in done], [r["stages_s"][s] or 0 for r in done])
                 for s in STAGES}
    exponents["peak_rss"] = fit_exponent([r["povs"] for r in done],
                                         [r["peak_rss_mib"] for r in done])
    return {"runs": table, "exponents": exponents, "load": load()}


def main(argv=None) -> int:
    """``python bench/scale.py [--grids 32,62,124] [--reuse 62=DIR] [--out FILE]``;
    ``--reuse N=DIR`` takes grid N from DIR (a run's metrics.json plus the
    ``measured.json`` written by an earlier scale run) instead of running it."""
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--grids", default="32,62,124")
    parser.add_argument("--reuse", action="append", default=[])
    parser.add_argument("--work", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "scale.json")
    args = parser.parse_args(argv)
    grids = [int(g) for g in args.grids.split(",") if g]
    existing = {}
    for item in args.reuse:
        grid, _, directory = item.partition("=")
        directory = Path(directory)
        existing[int(grid)] = {"run": json.loads((directory / "measured.json").read_text()),
                               "metrics": json.loads((directory / "metrics.json").read_text())}
    result = run_scale(grids, out_root=args.work, existing=existing)
    if args.work:
        for n in grids:
            if n not in existing and (args.work / f"scale-{n}").is_dir():
                (args.work / f"scale-{n}" / "measured.json").write_text(
                    json.dumps(result["runs"][str(n)], default=str))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2, default=str) + "\n")
    for n, row in result["runs"].items():
        stages = ", ".join(f"{s} {v:.3g}" for s, v in row["stages_s"].items() if v is not None)
        print(f"grid {n}: P={row['povs']} wall {row['wall_s']:.1f} s, peak "
              f"{row['peak_rss_mib']:.0f} MiB, load {row['load_before']}: {stages}")
    print("exponents (t ~ P^k):", {k: None if v is None else round(v, 2)
                                   for k, v in result["exponents"].items()})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
