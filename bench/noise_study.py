"""The naive agent's noise study: one run per imperfection, a table and a figure.

Runs ``bench/noisy_naive.py``'s ``run`` (the simulator wrapped by
``ImperfectSensing``, imperfections the agent is never told about) for
sensor noise, quantum, float32, motor noise, dropout and all combined, and
writes ``study.json``, ``study.md`` (a Markdown table) and ``study.png``
(coverage, wrong poses, pose precision, 2-D after affine residual,
trustworthiness and motor states per POV against each imperfection)::

    .venv/bin/python bench/noise_study.py --config config/smoke.yaml --out /tmp/noise_study
    .venv/bin/python bench/noise_study.py --config config/paper.yaml --jobs 2 --out DIR
    .venv/bin/python bench/noise_study.py --config config/paper.yaml --only "noise 1e-4"

``--jobs N`` runs N settings at a time, each in a process of its own (the
paper grid takes minutes a run); every run is seeded, so the rows do not
depend on N.
"""
from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
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

COLUMNS = [("rank, POV dim, space dim", "structure"), ("POVs", "pov.count"),
           ("coverage", "naive.coverage"), ("paper's positions", "naive.coverage_of_paper_positions"),
           ("wrong", "naive.wrong_poses"), ("changes accepted", "naive.state_changes_accepted"),
           ("pose error median", "naive.pose_error_median"),
           ("pose error p95", "naive.pose_error_p95"),
           ("2-D after residual", "quality.2d.after.affine_residual"),
           ("trust", "quality.2d.after.trustworthiness"),
           ("β0/β1", "betti"), ("searches and walks / POV", "naive.queries_per_pov"),
           ("motor states / POV", "naive.queries_total_per_pov"),
           ("motor states", "naive.queries_total"), ("wall (s)", "wall_s")]


BETTI_KEYS = ("topology.2d.after.betti0", "topology.2d.after.betti1")


def one(config: str, seed: int, out: str, name: str, imperfections: dict) -> dict:
    folder = f"{out}/{name.replace(' ', '_')}"
    summary = noisy_naive.run(config, seed, folder, **imperfections)
    return row_of(folder, name, summary["wall_s"])


def row_of(folder: str, name: str, wall_s: float) -> dict:
    """The study's row of the run written in ``folder``."""
    from sensorispace_ros import config as config_mod
    flat = config_mod.flatten(json.loads(Path(folder, "metrics.json").read_text()))
    row = {key: flat.get(key) for _, key in COLUMNS if key in flat}
    row.update({key: flat.get(key) for key in BETTI_KEYS})
    row["betti"] = "/".join(str(flat.get(key, "—")) for key in BETTI_KEYS)
    row["structure"] = ", ".join(str(flat.get(f"naive.{key}", "—"))
                                 for key in ("pose_rank", "pov_dim", "space_dim"))
    if not flat.get("pov.count"):            # no POV: nothing per POV, no pose to err
        for key in ("naive.queries_per_pov", "naive.queries_total_per_pov",
                    "naive.pose_error_median", "naive.pose_error_p95"):
            row[key] = None
    row.update(name=name, wall_s=wall_s, pov_count=flat.get("pov.count"))
    return row


def guarded(config: str, seed: int, out: str, name: str, imperfections: dict) -> dict:
    """``one``; a run that fails still has a row, naming the error."""
    try:
        return one(config, seed, out, name, imperfections)
    except Exception as error:
        return {"name": name, "error": f"{type(error).__name__}: {error}"}


def cell(value) -> str:
    if value is None:
        return "—"
    if isinstance(value, (int, float)) and not isinstance(value, bool) and abs(value) >= 1000:
        return f"{value:,.0f}"
    if isinstance(value, float):
        return f"{value:.4g}"
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

    # (title, metric key(s), log scale, the line a body must meet or None)
    panels = [("paper's positions", "naive.coverage_of_paper_positions", False, 0.9),
              ("wrong poses", "naive.wrong_poses", False, None),
              ("pose error p95", "naive.pose_error_p95", True, None),
              ("2-D after affine residual", "quality.2d.after.affine_residual", True, 1e-3),
              ("trustworthiness", "quality.2d.after.trustworthiness", False, 0.999),
              ("β0, β1 (2-D after)", BETTI_KEYS, False, 1.0),
              ("motor states per POV", "naive.queries_total_per_pov", True, None)]
    names = [row["name"] for row in rows]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.0 * len(panels)), sharex=True)
    for ax, (title, keys, log, line) in zip(axes, panels):
        keys = (keys,) if isinstance(keys, str) else keys
        width = 0.8 / len(keys)
        for k, key in enumerate(keys):
            values = [row.get(key) if row.get(key) is not None else float("nan")
                      for row in rows]
            ax.bar([i + (k - (len(keys) - 1) / 2) * width for i in range(len(rows))], values,
                   width=width, color=("tab:blue", "tab:orange")[k],
                   label=("β0", "β1")[k] if len(keys) > 1 else None)
        if log:
            ax.set_yscale("log")
        if line is not None:
            ax.axhline(line, color="tab:red", linestyle="--", linewidth=0.8)
        if len(keys) > 1:
            ax.legend(fontsize=7, loc="upper right")
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
    parser.add_argument("--jobs", type=int, default=1, help="settings run at a time")
    args = parser.parse_args()
    if args.jobs < 1:
        parser.error(f"--jobs: must be >= 1, got {args.jobs}")
    chosen = [(name, imperfections) for name, imperfections in SETTINGS
              if not args.only or name in args.only]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(guarded, args.config, args.seed, args.out, name, imperfections)
                   for name, imperfections in chosen]
        for future in as_completed(futures):
            print(json.dumps(future.result()), flush=True)
    rows = [future.result() for future in futures]          # in SETTINGS order
    Path(args.out).mkdir(parents=True, exist_ok=True)
    Path(args.out, "study.json").write_text(json.dumps(rows, indent=1))
    Path(args.out, "study.md").write_text(table(rows) + "\n")
    figure(rows, str(Path(args.out, "study.png")))
    print(table(rows))


if __name__ == "__main__":
    main()
