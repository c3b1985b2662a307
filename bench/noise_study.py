"""The naive agent's noise study: one run per imperfection, a table and a figure.

Runs ``bench/noisy_naive.py``'s ``run`` (the simulator wrapped by
``ImperfectSensing``, imperfections the agent is never told about) for
sensor noise, quantum, float32, motor noise, dropout and all combined, and
writes ``study.json``, ``study.md`` (a Markdown table) and ``study.png``
(coverage, wrong poses, pose precision, 2-D after affine residual,
trustworthiness and motor states per POV against each imperfection)::

    .venv/bin/python bench/noise_study.py --config config/smoke.yaml --out /tmp/noise_study
    .venv/bin/python bench/noise_study.py --config config/paper.yaml --only noise:1e-4

A run is one process at a time (the paper grid takes minutes per run).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import noisy_naive  # noqa: E402

SETTINGS = [
    ("none", {}),
    ("noise 1e-6", {"noise": 1e-6}), ("noise 1e-4", {"noise": 1e-4}),
    ("noise 1e-3", {"noise": 1e-3}), ("noise 1e-2", {"noise": 1e-2}),
    ("quantum 1e-4", {"quantum": 1e-4}), ("quantum 1e-3", {"quantum": 1e-3}),
    ("quantum 4e-3", {"quantum": 4e-3}), ("float32", {"float32": True}),
    ("motor noise 1e-4", {"motor_noise": 1e-4}), ("motor noise 1e-3", {"motor_noise": 1e-3}),
    ("dropout 1e-3", {"dropout": 1e-3}),
    ("combined", {"noise": 1e-3, "quantum": 1e-3, "motor_noise": 1e-3, "dropout": 1e-3}),
]

COLUMNS = [("POVs", "pov.count"), ("coverage", "naive.coverage"),
           ("wrong", "naive.wrong_poses"), ("changes accepted", "naive.state_changes_accepted"),
           ("pose error median", "naive.pose_error_median"),
           ("pose error p95", "naive.pose_error_p95"),
           ("2-D after residual", "quality.2d.after.affine_residual"),
           ("trust", "quality.2d.after.trustworthiness"),
           ("β0/β1", "betti"), ("queries / POV", "naive.queries_per_pov"),
           ("queries", "naive.queries_total"), ("wall (s)", "wall_s")]


def one(config: str, seed: int, out: str, name: str, imperfections: dict) -> dict:
    folder = f"{out}/{name.replace(' ', '_')}"
    summary = noisy_naive.run(config, seed, folder, **imperfections)
    from sensorispace_ros import config as config_mod
    flat = config_mod.flatten(json.loads(Path(folder, "metrics.json").read_text()))
    row = {key: flat.get(key) for _, key in COLUMNS if key in flat}
    row["betti"] = (f"{flat.get('topology.2d.after.betti0', '—')}/"
                    f"{flat.get('topology.2d.after.betti1', '—')}")
    row.update(name=name, wall_s=summary["wall_s"], pov_count=flat.get("pov.count"))
    return row


def cell(value) -> str:
    if value is None:
        return "—"
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def table(rows: list) -> str:
    head = "| setting | " + " | ".join(label for label, _ in COLUMNS) + " |"
    lines = [head, "|" + "---|" * (len(COLUMNS) + 1)]
    for row in rows:
        lines.append(f"| {row['name']} | "
                     + " | ".join(cell(row.get(key)) for _, key in COLUMNS) + " |")
    return "\n".join(lines)


def figure(rows: list, path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("coverage", "naive.coverage", False), ("wrong poses", "naive.wrong_poses", False),
              ("pose error p95", "naive.pose_error_p95", True),
              ("2-D after affine residual", "quality.2d.after.affine_residual", True),
              ("trustworthiness", "quality.2d.after.trustworthiness", False),
              ("motor states per POV", "naive.queries_per_pov", False)]
    names = [row["name"] for row in rows]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.0 * len(panels)), sharex=True)
    for ax, (title, key, log) in zip(axes, panels):
        values = [row.get(key) if row.get(key) is not None else float("nan") for row in rows]
        if log:
            values = [max(v, 1e-12) for v in values]
            ax.set_yscale("log")
        ax.bar(range(len(rows)), values, color="tab:blue")
        ax.set_ylabel(title, fontsize=8)
    axes[-1].set_xticks(range(len(rows)))
    axes[-1].set_xticklabels(names, rotation=45, ha="right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="/tmp/noise_study")
    parser.add_argument("--only", nargs="*", default=None,
                        help="setting names to run (default: all), e.g. 'noise 1e-4'")
    args = parser.parse_args()
    rows = []
    for name, imperfections in SETTINGS:
        if args.only and name not in args.only:
            continue
        try:
            rows.append(one(args.config, args.seed, args.out, name, imperfections))
        except Exception as error:      # a run that finds nothing still has a row
            rows.append({"name": name, "error": f"{type(error).__name__}: {error}"})
        print(json.dumps(rows[-1]), flush=True)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    Path(args.out, "study.json").write_text(json.dumps(rows, indent=1))
    Path(args.out, "study.md").write_text(table(rows) + "\n")
    figure(rows, str(Path(args.out, "study.png")))
    print(table(rows))


if __name__ == "__main__":
    main()
