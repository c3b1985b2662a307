"""Every benchmark in one command; a JSON file and a short table.

    PYTHONPATH=. python bench/run_all.py [--quick] [--out bench/results/bench.json]
        [--povs-from RESULTS_DIR] [--skip end_to_end,probe,...] [--scale]

Benchmarks (each prints its baseline and its ratio, measured in the same run):
  end_to_end   ``sensorispace reproduce`` paper and naive strategies, and the
               launched ROS graph (``sensorispace launch --no-record``), each
               a child process: wall, CPU, peak RSS. Config: paper.yaml
               (smoke.yaml with --quick).
  hausdorff    fast matrix vs blocked NumPy brute force on the paper run's
               POVs (seed 0; from --povs-from, else from the end_to_end paper
               run, else produced with offline.strategies.run_paper).
  cca          CCA per epoch vs a per-step (P, d) reference; regularisation
               per iteration and its averaging vs a Python loop.
  probe        graph probe round trip vs bare rclpy ping-pong, 1 row and a
               649-row batch.
  scale        (only with --scale) stage costs at grid 32, 62, 124 and the
               fitted exponent in the POV count; peak memory.
The machine is shared: every entry carries the load average around it.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

import numpy as np  # noqa: E402

from bench.child import REPO, child_environment, load, reproduce_command, run_measured  # noqa: E402

BENCHMARKS = ("end_to_end", "hausdorff", "cca", "probe")


def end_to_end(config: Path, work: Path, graph_timeout_s: float) -> dict:
    out = {"config": str(config.relative_to(REPO) if config.is_relative_to(REPO) else config)}
    for strategy in ("paper", "naive"):
        run_dir = work / f"e2e-{strategy}"
        measured = run_measured(reproduce_command(config, strategy, run_dir),
                                work / f"e2e-{strategy}.log")
        if measured["exit_code"] == 0:
            metrics = json.loads((run_dir / "metrics.json").read_text())
            measured["timings_s"] = metrics.get("timings_s", {})
            measured["povs"] = metrics.get("pov", {}).get("count")
        measured["results_dir"] = str(run_dir)
        out[f"offline_{strategy}"] = measured
    command = [sys.executable, "-m", "sensorispace_ros.cli", "launch", "--config", str(config),
               "--no-record", "--results", str(work / "graph"), "--run", "bench",
               "--timeout", str(graph_timeout_s)]
    graph = run_measured(command, work / "e2e-graph.log", env=child_environment(),
                         timeout_s=graph_timeout_s + 120)
    agent_log = work / "graph" / "bench" / "logs" / "agent.log"
    if agent_log.is_file():
        graph["agent_summary"] = " ".join(
            line.split("]: ", 1)[-1] for line in agent_log.read_text().splitlines()
            if "run over" in line or "transport:" in line) or None
    # wait4's rusage covers the child and the descendants it waited for: the
    # node processes the launcher stopped and reaped.
    graph["note"] = ("cpu_s sums the launcher and its node processes; peak_rss_mib is the "
                     "largest of them")
    out["graph"] = graph
    naive = out["offline_naive"]
    if naive["exit_code"] == 0 and graph["exit_code"] == 0:
        out["graph_over_offline_naive"] = graph["wall_s"] / naive["wall_s"]
    return out


def paper_povs(povs_from: Path | None, e2e: dict | None, quick: bool):
    """POVs, pairs, set ids of the paper strategy, seed 0."""
    candidates = [povs_from] if povs_from else []
    if e2e and e2e.get("offline_paper", {}).get("exit_code") == 0 and not quick:
        candidates.append(Path(e2e["offline_paper"]["results_dir"]))
    for directory in candidates:
        with np.load(Path(directory) / "arrays.npz") as arrays:
            return arrays["povs"], arrays["pairs"], arrays["set_ids"], str(directory)
    from sensorispace_ros import config
    from sensorispace_ros.offline.strategies import run_paper
    cfg = config.load_config(REPO / "config" / ("smoke.yaml" if quick else "paper.yaml"))
    produced = run_paper(cfg, 0)
    return produced.povs, produced.pairs, produced.set_ids, "strategies.run_paper (in process)"


def table(results: dict) -> str:
    rows = []

    def row(name, value, baseline, ratio, extra=""):
        fmt = lambda v: "-" if v is None else (f"{v:.4g}" if isinstance(v, float) else str(v))  # noqa: E731
        rows.append(f"{name:34s} {fmt(value):>10s} {fmt(baseline):>10s} {fmt(ratio):>7s}  {extra}")

    rows.append(f"{'benchmark':34s} {'value':>10s} {'baseline':>10s} {'ratio':>7s}  notes")
    h = results.get("hausdorff")
    if h:
        row("hausdorff matrix [s]", h["fast_s"], h["bruteforce_s"], h["ratio"],
            f"{h.get('kernel', 'numpy')}; 1 thread {h['fast_1thread_s']:.3g} s "
            f"(x{h['ratio_1thread']:.3g}, CPU x{h['ratio_cpu_1thread']:.3g}); "
            f"NumPy path {h.get('numpy_path_s', float('nan')):.3g} s; "
            f"max|diff| {h['max_abs_diff']:.3g}; P={h['povs'][0]}; load {h['load_before'][0]}")
    c = results.get("cca")
    if c:
        for dim, v in c["cca"]["dims"].items():
            row(f"CCA {dim} per epoch [ms]", v["per_epoch_ms"], v["baseline_per_epoch_ms"],
                v["ratio"], f"fit {v['fit_s']:.3g} s; max|diff| {v['max_abs_diff_vs_baseline']:.2g}; "
                f"{v.get('kernel', 'numpy')}; NumPy loop "
                f"{v.get('numpy_loop_per_epoch_ms', float('nan')):.3g} ms/epoch, "
                f"max|diff| {v.get('max_abs_diff_vs_numpy_loop', float('nan')):.2g}")
        r = c["regularization"]
        row("regularisation averaging [ms]", r["averaging_ms"], r["averaging_baseline_ms"],
            r["averaging_ratio"], f"max|diff| {r['averaging_max_abs_diff']:.2g}")
        row("regularisation iteration 2d [s]", r["per_iteration_s_2d"], None, None,
            f"{r['iterations']} iterations, CCA {r['cca_epochs']} epochs")
    p = results.get("probe")
    if p:
        for rows_, v in p["rows"].items():
            row(f"probe round trip {rows_} row(s) [ms]", v["graph_median_ms"], v["bare_median_ms"],
                v["ratio_median"], f"mean ratio {v['ratio_mean']:.3g}; lean echo "
                f"{v['lean_bare_median_ms']:.3g} ms (x{v['ratio_median_vs_lean_bare']:.3g}); "
                f"net of body compute {v['ratio_median_net_of_compute']:.3g}; body compute "
                f"{v['body_compute_ms']:.3g} ms; load {p['load_before'][0]}")
    e = results.get("end_to_end")
    if e:
        for key in ("offline_paper", "offline_naive", "graph"):
            v = e[key]
            extra = f"exit {v['exit_code']}; cpu {v['cpu_s']:.3g} s; peak {v['peak_rss_mib']:.0f} MiB"
            if "timings_s" in v:
                extra += f"; total w/o figures {v['timings_s'].get('total', 0):.3g} s"
            extra += f"; load {v['load_before'][0]}"
            baseline = e["offline_naive"]["wall_s"] if key == "graph" else None
            ratio = e.get("graph_over_offline_naive") if key == "graph" else None
            row(f"end to end {key} [s]", v["wall_s"], baseline, ratio, extra)
    s = results.get("scale")
    if s:
        for n, v in s["runs"].items():
            row(f"scale grid {n} total [s]", v["stages_s"].get("total"), None, None,
                f"P={v['povs']}; peak {v['peak_rss_mib']:.0f} MiB; load {v['load_before'][0]}")
        rows.append("fitted exponents (t ~ P^k): " + ", ".join(
            f"{k} {v:.2f}" for k, v in s["exponents"].items() if v is not None))
    return "\n".join(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="smoke config, fewer repeats (a minute or two)")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "bench.json")
    parser.add_argument("--povs-from", type=Path, default=None,
                        help="results dir of a paper run (arrays.npz) to take the POVs from")
    parser.add_argument("--skip", default="", help="comma-separated benchmarks to skip: "
                        + ",".join(BENCHMARKS))
    parser.add_argument("--scale", action="store_true",
                        help="also run the scale study (grid 32, 62, 124; many minutes)")
    parser.add_argument("--work", type=Path, default=None,
                        help="keep the runs' results here (default: a temporary directory)")
    args = parser.parse_args(argv)
    skip = {s for s in args.skip.split(",") if s}
    unknown = skip - set(BENCHMARKS)
    if unknown:
        parser.error(f"--skip: unknown benchmark(s) {sorted(unknown)}; known: {BENCHMARKS}")

    from bench import kernels, probe_roundtrip
    config = REPO / "config" / ("smoke.yaml" if args.quick else "paper.yaml")
    results: dict = {"started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                     "quick": args.quick, "machine": {"cpus": os.cpu_count(),
                                                      "python": platform.python_version(),
                                                      "numpy": np.__version__},
                     "load_start": load()}
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        if "end_to_end" not in skip:
            print("[bench] end to end ...", flush=True)
            results["end_to_end"] = end_to_end(config, work, 600.0 if args.quick else 3600.0)
        if {"hausdorff", "cca"} - skip:
            povs, pairs, set_ids, source = paper_povs(args.povs_from, results.get("end_to_end"),
                                                      args.quick)
            results["povs_source"] = source
        if "hausdorff" not in skip:
            print(f"[bench] hausdorff on {povs.shape} ...", flush=True)
            results["hausdorff"] = kernels.bench_hausdorff(
                povs, repeats=1 if args.quick else 3)
        if "cca" not in skip:
            print("[bench] cca and regularisation ...", flush=True)
            from sensorispace_ros.core.hausdorff import hausdorff_matrix
            distance = hausdorff_matrix(povs)
            epochs = 5 if args.quick else 50
            results["cca"] = {
                "cca": kernels.bench_cca(distance, n_epochs=epochs,
                                         baseline_epochs=1 if args.quick else 2),
                "regularization": kernels.bench_regularization(
                    distance, pairs, set_ids, n_iterations=2 if args.quick else 10,
                    n_epochs=epochs)}
        if "probe" not in skip:
            print("[bench] probe round trip ...", flush=True)
            results["probe"] = probe_roundtrip.measure(
                REPO / "config" / "smoke.yaml", batch_rows=649,
                rounds=4 if args.quick else 10,
                per_round={1: 50, 649: 10} if args.quick else {1: 100, 649: 20})
        if args.scale:
            from bench import scale
            print("[bench] scale study ...", flush=True)
            results["scale"] = scale.run_scale(out_root=work)
    results["load_end"] = load()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2, default=str) + "\n")
    print(table(results))
    print(f"[bench] wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
