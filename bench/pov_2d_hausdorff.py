"""How many samples a 2-D point of view needs: the Hausdorff distance between
sampled POVs against a much denser sampling of the same POVs.

    PYTHONPATH=. python bench/pov_2d_hausdorff.py [--counts 200,400,800,1600,3200]
        [--matrix 800,1600] [--order] [--out bench/results/pov_2d_hausdorff.json]

POV pairs come from the paper strategy's exploration of
config/bodies/five-joint.yaml (seed 0): ten POVs spread over the tip's
distance from the base, each with the POVs one grid step away along x and
along y, two steps and five steps away. Each pair's Hausdorff distance
(``core.hausdorff.hausdorff_matrix``) with ``N`` samples per POV
(``surfaces.sample_surface``) is compared with the reference: every
candidate of a 384-angle lattice per chart (~10^5 states per POV). For
scale, the same for the paper body's 1-D POVs (N = 100 against 4,000 walk
samples). ``--matrix``: the sampling time and the Hausdorff matrix of all
the run's POVs (every ``--every``-th) at those counts; ``--counts ""``
leaves the error table out. ``--order``: the Hausdorff matrix of every
fourth POV (1,600 samples) in the samplers' order (a nearest-neighbour
tour) and in a random one. The machine is shared: CPU times are reported
beside wall times, with the load.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

if str(Path(__file__).resolve().parent.parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.child import REPO, load  # noqa: E402
from sensorispace_ros.config import load_config  # noqa: E402
from sensorispace_ros.core.hausdorff import hausdorff_matrix  # noqa: E402
from sensorispace_ros.core.paper.exploration import build_world, explore_paper  # noqa: E402
from sensorispace_ros.core.paper.points_of_view import sample_points_of_view  # noqa: E402
from sensorispace_ros.core.paper.surfaces import sample_surface, surface_candidates  # noqa: E402
from sensorispace_ros.core.run_world import world_params  # noqa: E402

OFFSETS = {"1 step x": (1, 0), "1 step y": (0, 1), "2 steps": (2, 1), "5 steps": (5, 0)}
REFERENCE_GRID = 384


def explored(body: str):
    cfg = load_config(REPO / "config" / "bodies" / f"{body}.yaml")
    world = build_world(0, world_params(cfg))
    result = explore_paper(m0=world.m0, grid=world.grid, events=world.events,
                           initial_center=world.initial_center, body_arm=world.arm)
    return world, result


def pairs_of(world, result, bases: int = 10) -> list:
    """``(label, i, j)`` POV index pairs: bases spread over the tip radius,
    each with its neighbours at ``OFFSETS`` grid steps (when compensated)."""
    positions = result.true_poses[:, :2]
    radius = np.hypot(positions[:, 0], positions[:, 1])
    order = np.argsort(radius)
    chosen = order[(np.linspace(0.05, 0.95, bases) * (len(order) - 1)).astype(int)]
    out = []
    for i in chosen:
        for label, (dx, dy) in OFFSETS.items():
            target = positions[i] + world.spacing * np.array([dx, dy])
            gap = np.linalg.norm(positions - target, axis=1)
            j = int(np.argmin(gap))
            if gap[j] < world.spacing / 4:
                out.append((label, int(i), j))
    return out


def pair_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Hausdorff distance of two sample sets of any sizes (the smaller one's
    samples repeated: the same set)."""
    n = max(len(a), len(b))
    pad = [s[np.arange(n) * len(s) // n] for s in (a, b)]
    return float(hausdorff_matrix(np.stack(pad))[0, 1])


def surface_errors(world, result, pairs, counts) -> dict:
    arm = world.arm
    involved = sorted({k for _, i, j in pairs for k in (i, j)})
    reference_sets = {k: surface_candidates(arm, result.motor_states[k], grid=REFERENCE_GRID)
                      for k in involved}
    reference = {(i, j): pair_distance(reference_sets[i], reference_sets[j]) for _, i, j in pairs}
    sample_surface(arm, result.motor_states[0], 50)         # compile the loops first
    rows = {}
    for n in counts:
        started, cpu = time.perf_counter(), time.process_time()
        sampled = {k: sample_surface(arm, result.motor_states[k], n) for k in involved}
        cost = {"wall_s_per_pov": (time.perf_counter() - started) / len(involved),
                "cpu_s_per_pov": (time.process_time() - cpu) / len(involved)}
        errors = {label: [] for label in OFFSETS}
        for label, i, j in pairs:
            value = pair_distance(sampled[i], sampled[j])
            errors[label].append((value - reference[(i, j)]) / reference[(i, j)])
        rows[n] = {**cost, "relative_error": {
            label: {"pairs": len(e), "median": float(np.median(np.abs(e))),
                    "max": float(np.max(np.abs(e))), "mean_signed": float(np.mean(e))}
            for label, e in errors.items() if e}}
        print(f"N={n}: {json.dumps(rows[n])}", flush=True)
    return {"reference_grid": REFERENCE_GRID,
            "reference_candidates_median": int(np.median([len(s) for s in
                                                          reference_sets.values()])),
            "reference_distance": {label: float(np.median([reference[(i, j)] for lab, i, j
                                                           in pairs if lab == label]))
                                   for label in OFFSETS},
            "counts": rows}


def loop_errors(world, result, pairs, count: int = 100, dense: int = 4000) -> dict:
    """The same measure for 1-D POVs (the paper body): ``count`` walk samples
    against ``dense``."""
    involved = sorted({k for _, i, j in pairs for k in (i, j)})
    states = result.motor_states[involved]
    index = {k: n for n, k in enumerate(involved)}
    few = sample_points_of_view(states, n_samples=count, body_arm=world.arm).samples
    many = sample_points_of_view(states, n_samples=dense, body_arm=world.arm).samples
    errors = {label: [] for label in OFFSETS}
    for label, i, j in pairs:
        ref = pair_distance(many[index[i]], many[index[j]])
        errors[label].append((pair_distance(few[index[i]], few[index[j]]) - ref) / ref)
    return {label: {"pairs": len(e), "median": float(np.median(np.abs(e))),
                    "max": float(np.max(np.abs(e)))} for label, e in errors.items() if e}


def matrix_costs(world, result, counts, every: int = 1) -> dict:
    sample_surface(world.arm, result.motor_states[0], 50)   # compile the loops first
    out = {}
    for n in counts:
        started, cpu = time.perf_counter(), time.process_time()
        povs = np.stack([sample_surface(world.arm, m, n) for m in result.motor_states[::every]])
        sampling = (time.perf_counter() - started, time.process_time() - cpu)
        started, cpu = time.perf_counter(), time.process_time()
        hausdorff_matrix(povs)
        out[n] = {"povs": len(povs), "sampling_wall_s": sampling[0], "sampling_cpu_s": sampling[1],
                  "hausdorff_wall_s": time.perf_counter() - started,
                  "hausdorff_cpu_s": time.process_time() - cpu, "load": load()}
        print(f"matrix N={n}: {json.dumps(out[n])}", flush=True)
    return out


def order_costs(world, result, n: int = 1600, seed: int = 0) -> dict:
    povs = np.stack([sample_surface(world.arm, m, n) for m in result.motor_states[::4]])
    rng = np.random.default_rng(seed)
    shuffled = np.stack([p[np.concatenate([[0], 1 + rng.permutation(n - 1)])] for p in povs])
    out = {"povs": len(povs)}
    for name, batch in (("tour", povs), ("random", shuffled)):
        started, cpu = time.perf_counter(), time.process_time()
        matrix = hausdorff_matrix(batch)
        out[name] = {"wall_s": time.perf_counter() - started,
                     "cpu_s": time.process_time() - cpu, "sum": float(matrix.sum())}
    out["load"] = load()
    print(f"order: {json.dumps(out)}", flush=True)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", default="200,400,800,1600,3200")
    parser.add_argument("--matrix", default="", help="sample counts for the full matrix")
    parser.add_argument("--every", type=int, default=1, help="--matrix on every k-th POV")
    parser.add_argument("--order", action="store_true", help="tour against random order")
    parser.add_argument("--out", default=str(REPO / "bench" / "results" / "pov_2d_hausdorff.json"))
    args = parser.parse_args(argv)
    counts = [int(v) for v in args.counts.split(",") if v]
    report = {"load_before": load()}
    world, result = explored("five-joint")
    pairs = pairs_of(world, result)
    report["pairs"] = len(pairs)
    if counts:
        report["surface"] = surface_errors(world, result, pairs, counts)
        paper_world, paper_result = explored("paper")
        report["loop_n100_vs_4000"] = loop_errors(paper_world, paper_result,
                                                  pairs_of(paper_world, paper_result))
        print(f"1-D: {json.dumps(report['loop_n100_vs_4000'])}", flush=True)
    if args.matrix:
        report["matrix"] = matrix_costs(world, result, [int(v) for v in args.matrix.split(",")],
                                        args.every)
    if args.order:
        report["order"] = order_costs(world, result)
    report["load_after"] = load()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(report, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
