"""Coverage and wrong poses against the mean change interval (``world.clock: rows``).

One naive exploration per mean interval on the row clock (``core.clocked_run.run_on_clock``),
judged by ground truth (``evaluation.naive.evaluate_naive_run`` and
``evaluation.clock.clock_metrics``), its distinct positions against the lockstep run's
(``world.clock: agent``, run here unless ``--lockstep`` gives its count). Writes
``study.json`` (every run's numbers), ``study.md`` (a Markdown table) and ``study.png``
(coverage, wrong poses and motor states per POV against the interval), and prints the
smallest interval whose coverage reaches ``--target``::

    .venv/bin/python bench/clock_study.py --config config/smoke.yaml --out /tmp/clock_study
    nice -n 10 .venv/bin/python bench/clock_study.py --config config/paper.yaml \\
        --lockstep 648 --out /tmp/clock_study_paper

``--noise 1e-3`` sets ``world.retina.noise`` (the agent measures it; nothing tells it);
``--set naive.clock_walk_attempts=4`` any other parameter.
Runs are one process, one after the other; ``--intervals`` takes a subset and
``--resume`` keeps the runs ``study.json`` already holds.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

INTERVALS = (250, 500, 1000, 2000, 5000, 10000)

COLUMNS = [("distinct positions", "naive.distinct_positions"), ("coverage", "coverage"),
           ("POVs", "povs"), ("wrong poses", "naive.wrong_poses"),
           ("changes accepted", "naive.state_changes_accepted"),
           ("accepted across a change", "naive.accepted_across_change"),
           ("recall", "naive.clock.recall"),
           ("false detections", "naive.clock.false_detection_rate"),
           ("reactions kept / undone", "reactions"),
           ("motor states", "naive.queries_total"), ("per POV", "naive.clock.queries_per_pov"),
           ("lost rows", "naive.clock.lost_rows"), ("wall (s)", "wall_s")]


def overrides(seed: int, noise: float, settings=()) -> dict:
    """Config overrides: the seed, the sensor noise, ``key=value`` settings (YAML values)."""
    import yaml

    values = {"seed": seed}
    if noise:
        values["world.retina.noise"] = noise
    for setting in settings:
        key, _, value = setting.partition("=")
        values[key.strip()] = yaml.safe_load(value)
    return values


def explore(config_path: str, seed: int, noise: float, clock: str, interval: float,
            settings=()) -> dict:
    """One exploration on ``clock``; its ground-truth numbers."""
    from sensorispace_ros import config
    from sensorispace_ros.core.clocked_run import run_on_clock
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.evaluation.clock import clock_metrics
    from sensorispace_ros.evaluation.naive import evaluate_naive_run

    cfg = config.load_config(config_path, {**overrides(seed, noise, settings), "world.clock": clock,
                                           "world.change_interval": float(interval)})
    world = run_world(cfg)
    started = time.perf_counter()
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), clock, interval=float(interval))
    wall = time.perf_counter() - started
    metrics = dict(evaluate_naive_run(run, world).metrics)
    metrics.update(clock_metrics(run, world))
    metrics["naive.queries_total"] = int(run.agent.queries_total)
    metrics["naive.queries_by_stage"] = dict(run.agent.queries_by_stage)
    metrics["povs"] = int(len(run.povs))
    metrics["wall_s"] = round(wall, 1)
    return {k: (v.item() if hasattr(v, "item") else v) for k, v in metrics.items()
            if isinstance(v, (int, float, dict, str)) or hasattr(v, "item")}


def cell(row: dict, key: str) -> str:
    if key == "reactions":
        if "naive.clock.reactions" not in row:
            return "–"
        return f"{row['naive.clock.reactions']} / {row['naive.clock.undone_reactions']}"
    value = row.get(key)
    if value is None:
        return "–"
    if key == "naive.clock.false_detection_rate":
        return f"{100 * value:.2g} %"
    if isinstance(value, float):
        return f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"
    return f"{value:,}" if isinstance(value, int) else str(value)


def table(rows: list) -> str:
    head = "| mean interval (rows) | " + " | ".join(str(r["interval"]) for r in rows) + " |"
    lines = [head, "|---|" + "---|" * len(rows)]
    for label, key in COLUMNS:
        lines.append(f"| {label} | " + " | ".join(cell(r, key) for r in rows) + " |")
    return "\n".join(lines)


def smallest(rows: list, target: float):
    """The smallest interval from which on every longer one reaches ``target``."""
    good = None
    for row in sorted(rows, key=lambda r: -r["interval"]):
        if not row["coverage"] >= target:      # NaN: not reached
            break
        good = row["interval"]
    return good


def figure(rows: list, lockstep: int, target: float, path: str, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = sorted(rows, key=lambda r: r["interval"])
    x = [r["interval"] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    axes[0].plot(x, [r["coverage"] for r in rows], "o-")
    axes[0].axhline(target, color="grey", ls="--", lw=1)
    axes[0].set_ylabel(f"distinct positions / lockstep's {lockstep}")
    axes[1].plot(x, [r.get("naive.wrong_poses", 0) for r in rows], "o-", label="wrong poses")
    axes[1].plot(x, [r.get("naive.accepted_across_change", 0) for r in rows], "s--",
                 label="accepted across a change")
    axes[1].legend(fontsize=8)
    axes[1].set_ylabel("count")
    axes[2].plot(x, [r.get("naive.clock.queries_per_pov", 0) for r in rows], "o-")
    axes[2].set_ylabel("motor states probed per POV")
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("mean change interval (rows)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--noise", type=float, default=0.0)
    parser.add_argument("--intervals", type=float, nargs="*", default=list(INTERVALS))
    parser.add_argument("--lockstep", type=int, default=None,
                        help="the lockstep run's distinct positions (else it is run)")
    parser.add_argument("--target", type=float, default=0.9)
    parser.add_argument("--out", default="/tmp/clock_study")
    parser.add_argument("--figure", default=None, help="also write the figure here")
    parser.add_argument("--resume", action="store_true")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="a config override, e.g. naive.clock_walk_attempts=4")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    store = out / "study.json"
    done = json.loads(store.read_text()) if args.resume and store.exists() else {}
    lockstep = args.lockstep if args.lockstep is not None else done.get("lockstep")
    if lockstep is None:
        lockstep = explore(args.config, args.seed, args.noise, "agent", 1.0, args.set)[
            "naive.distinct_positions"]
    rows = [r for r in done.get("rows", []) if r["interval"] in args.intervals]
    for interval in args.intervals:
        if any(r["interval"] == interval for r in rows):
            continue
        row = explore(args.config, args.seed, args.noise, "rows", interval, args.set)
        row["interval"] = int(interval)
        # A lockstep run that covers nothing leaves nothing to compare with.
        row["coverage"] = row["naive.distinct_positions"] / lockstep if lockstep else float("nan")
        rows.append(row)
        rows.sort(key=lambda r: r["interval"])
        store.write_text(json.dumps({"config": args.config, "seed": args.seed,
                                     "noise": args.noise, "set": args.set, "lockstep": lockstep,
                                     "rows": rows}, indent=1))
        print(f"interval {interval:g}: coverage {row['coverage']:.3f}, wrong "
              f"{row.get('naive.wrong_poses')}, {row['wall_s']} s", flush=True)
    best = smallest(rows, args.target)
    text = table(rows) + (f"\n\nLockstep distinct positions: {lockstep}. Smallest mean interval "
                          f"with coverage >= {args.target}: {best}.\n")
    (out / "study.md").write_text(text)
    title = (f"{args.config}, seed {args.seed}, "
             + (f"sensor noise {args.noise:g}" if args.noise else "noiseless"))
    figure(rows, lockstep, args.target, str(out / "study.png"), title)
    if args.figure:
        figure(rows, lockstep, args.target, args.figure, title)
    print(text)


if __name__ == "__main__":
    main()
