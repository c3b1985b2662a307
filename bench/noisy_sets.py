"""What a naive run's 2-D after residual owes to its equality sets and to its POVs.

Reads the ``arrays.npz`` of a naive run (``sensorispace reproduce --strategy
naive`` or ``bench/noisy_naive.py --out DIR``) and regularises its Hausdorff
metric again (the run's configuration and seed, ``offline.representation``'s
2-D chain) with, one JSON line each:

* ``own``: the run's equality sets;
* ``right``: those sets without their wrong pairs (ground truth: a pair whose
  true displacement lies more than half a grid step from its set's median);
* ``sample N`` (``--sample N ...``): N of the run's pairs, whole sets drawn
  at random (``--seed``), as a run finding fewer would have them;
* ``truth``: every pair of the run's POVs, one set per displacement between
  grid positions: perfect sets, so what is left is the POVs' own pose errors;
* ``own + segments`` / ``right + segments`` (``--segments N``): those sets
  and the sets of segments they imply (``clock_equality.translated_sets``,
  N changes a set, as the agent on the row clock takes them);
* ``truth, within X`` (``--within X ...``): perfect sets of the POVs whose
  true position lies within X grid steps of the lattice (the one whose phase
  is the positions' circular mean);
* ``own, trimmed`` (``--trimmed``): the run's sets without the found pairs
  its lattice's trimming drops (the found sets told from the implied ones by
  their numbering, ``found_count``);
* ``own + lattice`` (``--lattice``): those sets and the sets their lattice
  implies (``lattice_sets.lattice_equalities``, the agent's ``lattice_support``),
  with the pairs the trimming dropped (and how many of them are wrong), the
  POVs placed and taken (run the agent with ``naive.lattice_sets: false`` to
  read its found sets alone);
* ``truth, samples on their pose`` and ``truth, samples on the lattice``
  (``--ideal``): perfect sets, every POV sample moved by the forward model
  onto its POV's own pose, then onto that pose snapped to the lattice (the
  Hausdorff metric computed again): what the walks' drift and what the POVs'
  offsets each leave.

Each line: pairs, sets, wrong pairs, the 2-D after affine residual, and the
largest offset of a POV's true position from the lattice of the first POV's
(grid steps)::

    .venv/bin/python bench/noisy_sets.py /tmp/noisy_naive --sample 60000 150000 --segments 150

Diagnostics only: nothing here is the agent's.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from sensorispace_ros.core import quality
from sensorispace_ros.core.arm import Arm, wrap_angle
from sensorispace_ros.core.hausdorff import hausdorff_matrix
from sensorispace_ros.core.naive.clock_equality import translated_sets
from sensorispace_ros.core.naive.lattice_sets import lattice_equalities, set_medians
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.seeding import CounterStream
from sensorispace_ros.offline.representation import _dimension_chain


def wrong_pairs(true_positions, pairs, set_ids, step) -> np.ndarray:
    """(K,) bool: pairs whose true displacement lies more than half ``step``
    from the median displacement of their set."""
    shift = true_positions[pairs[:, 1]] - true_positions[pairs[:, 0]]
    return np.linalg.norm(shift - set_medians(shift, set_ids), axis=1) > 0.5 * step


def true_sets(true_positions, step):
    """Every pair of POVs, one set per displacement in whole grid steps (sets of
    two pairs or more)."""
    i, j = np.triu_indices(len(true_positions), 1)
    shift = np.rint((true_positions[j] - true_positions[i]) / step).astype(int)
    _, set_ids = np.unique(shift, axis=0, return_inverse=True)
    set_ids = set_ids.reshape(-1)
    keep = np.bincount(set_ids)[set_ids] >= 2
    return np.stack([i, j], axis=1)[keep], set_ids[keep]


def sampled_sets(pairs, set_ids, n_pairs, rng):
    """Whole sets drawn at random until ``n_pairs`` pairs."""
    order = rng.permutation(np.unique(set_ids))
    sizes = np.bincount(set_ids)[order]
    keep = np.isin(set_ids, order[np.cumsum(sizes) <= n_pairs])
    return pairs[keep], set_ids[keep]


def with_segments(pairs, set_ids, n_povs, per_set, seed):
    """``pairs``/``set_ids`` and the sets of segments they imply, numbered after them."""
    extra, extra_ids = translated_sets(pairs, set_ids, n_povs, per_set,
                                       stream=CounterStream(seed, "naive.clock_translated"))
    first = int(set_ids.max()) + 1 if len(set_ids) else 0
    return np.concatenate([pairs, extra]), np.concatenate([set_ids, extra_ids + first])


def lattice_offsets(positions, step):
    """(P,) distance in grid steps of each position from the lattice whose phase
    is the positions' circular mean, and the positions snapped to it."""
    units = positions / step
    phase = np.angle(np.exp(2j * np.pi * units).mean(axis=0)) / (2.0 * np.pi)
    snapped = np.rint(units - phase) + phase
    return np.linalg.norm(units - snapped, axis=1), snapped * step


def moved_onto(arm, povs, poses, iterations=6):
    """Each POV's samples moved by the least joint change (Gauss-Newton on the
    forward model) onto its pose in ``poses`` (P, 3)."""
    motor = np.array(povs, dtype=float)
    for _ in range(iterations):
        diff = arm.forward(motor) - poses[:, None, :]
        diff[..., 2] = wrap_angle(diff[..., 2])
        motor -= np.einsum("...ij,...j->...i", np.linalg.pinv(arm.jacobian(motor)), diff)
    return motor


def ideal_variants(arrays, cfg, step, within):
    """The ``--within`` and ``--ideal`` variants: (name, pairs, set_ids, arrays)."""
    offsets, snapped = lattice_offsets(arrays["true_positions"], step)
    variants = []
    for limit in within:
        keep = np.flatnonzero(offsets <= limit)
        subset = dict(arrays, hausdorff=arrays["hausdorff"][np.ix_(keep, keep)],
                      true_positions=arrays["true_positions"][keep])
        variants.append((f"truth, within {limit}",
                         *true_sets(subset["true_positions"], step), subset))
    if cfg is not None:
        arm, poses = Arm.from_config(cfg["arm"]), np.asarray(arrays["true_poses"], dtype=float)
        lattice_poses = poses.copy()
        lattice_poses[:, :2] += snapped - arrays["true_positions"]
        on_pose = dict(arrays, hausdorff=hausdorff_matrix(moved_onto(arm, arrays["povs"], poses)))
        on_lattice = dict(arrays, true_positions=snapped, hausdorff=hausdorff_matrix(
            moved_onto(arm, arrays["povs"], lattice_poses)))
        variants += [("truth, samples on their pose", *true_sets(on_pose["true_positions"], step),
                      on_pose),
                     ("truth, samples on the lattice", *true_sets(snapped, step), on_lattice)]
    return variants


def lattice_variant(pairs, set_ids, wrong, n_povs, cfg):
    """``own + lattice``: the found sets, then those their lattice implies;
    prints what the trimming dropped and placed."""
    support = cfg.get("naive", {}).get("lattice_support", NaiveParams().lattice_support)
    found = lattice_equalities(pairs, set_ids, n_povs, support)
    kept = found.kept if found.kept is not None else np.ones(len(pairs), dtype=bool)
    print(json.dumps({"lattice": found.placed > 0, "dropped": int(np.count_nonzero(~kept)),
                      "dropped_wrong": int(np.count_nonzero(~kept & wrong)),
                      "placed": found.placed, "taken": found.usable,
                      "implied_pairs": int(len(found.pairs))}), flush=True)
    first = int(set_ids.max()) + 1 if len(set_ids) else 0
    return ("own + lattice", np.concatenate([pairs, found.pairs]),
            np.concatenate([set_ids, found.set_ids + first]))


def found_count(pairs, set_ids, n_povs, support, samples=None) -> int:
    """How many of the sets (numbered in order) the agent found itself: the
    sets its lattice implies are numbered after them, so the first ``b``
    whose found sets' lattice implies exactly the sets from ``b`` on (a
    fixed point, found in a few steps; every set where none implies any)."""
    total = int(set_ids.max()) + 1 if len(set_ids) else 0
    count, seen = total // 2, set()
    while count not in seen:
        seen.add(count)
        found = set_ids < count
        implied = lattice_equalities(pairs[found], set_ids[found], n_povs, support, samples=samples)
        count = total - len(np.unique(implied.set_ids))
    return count


def trimmed_variant(pairs, set_ids, n_povs, cfg, samples=None):
    """``own, trimmed``: the run's sets without the found pairs its lattice's
    trimming drops (``lattice_sets.trimmed_lattice``; the agent hands them
    to the representation all the same); prints how many it drops."""
    support = cfg.get("naive", {}).get("lattice_support", NaiveParams().lattice_support)
    found = set_ids < found_count(pairs, set_ids, n_povs, support, samples)
    kept = lattice_equalities(pairs[found], set_ids[found], n_povs, support, samples=samples).kept
    keep = np.ones(len(pairs), dtype=bool)
    if kept is not None:
        keep[np.flatnonzero(found)[~kept]] = False
    print(json.dumps({"found_pairs": int(found.sum()), "trimmed": int(np.count_nonzero(~keep))}))
    return "own, trimmed", pairs[keep], set_ids[keep]


def residual(arrays, cfg, pairs, set_ids) -> float:
    chain = _dimension_chain(arrays["hausdorff"], pairs, set_ids, cfg, int(arrays["seed"]),
                             "2d", 2)
    return quality.affine_residual(chain["iterations"][-1], arrays["true_positions"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run", help="a naive run's output directory (its arrays.npz)")
    parser.add_argument("--sample", type=int, nargs="*", default=[])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--within", type=float, nargs="*", default=[],
                        help="also perfect sets of the POVs this near the lattice (grid steps)")
    parser.add_argument("--ideal", action="store_true",
                        help="also perfect sets of the samples moved onto their pose, "
                             "then onto the lattice")
    parser.add_argument("--lattice", action="store_true",
                        help="also own with the sets their lattice implies")
    parser.add_argument("--trimmed", action="store_true",
                        help="also own without the found pairs the lattice's trimming drops")
    parser.add_argument("--segments", type=int, default=0,
                        help="also each of own and right with its sets of segments "
                             "(this many changes a set; 0: not)")
    args = parser.parse_args()
    arrays = dict(np.load(Path(args.run) / "arrays.npz"))
    cfg = json.loads(str(arrays["config_json"]))
    positions, step = arrays["true_positions"], float(arrays["grid_spacing"])
    pairs, set_ids = arrays["pairs"], arrays["set_ids"]
    wrong = wrong_pairs(positions, pairs, set_ids, step)
    offset = (positions - positions[0]) / step
    lattice = float(np.max(np.linalg.norm(offset - np.rint(offset), axis=1)))
    rng = np.random.default_rng(args.seed)
    variants = [("own", pairs, set_ids), ("right", pairs[~wrong], set_ids[~wrong])]
    if args.segments:
        variants += [(f"{name} + segments", *with_segments(p, s, len(positions), args.segments,
                                                            args.seed))
                     for name, p, s in variants[:2]]
    if args.lattice:
        variants.append(lattice_variant(pairs, set_ids, wrong, len(positions), cfg))
    if args.trimmed:
        variants.append(trimmed_variant(pairs, set_ids, len(positions), cfg, arrays["povs"]))
    variants += [(f"sample {n}", *sampled_sets(pairs, set_ids, n, rng)) for n in args.sample]
    variants.append(("truth", *true_sets(positions, step)))
    variants = [(*v, arrays) for v in variants] + \
        ideal_variants(arrays, cfg if args.ideal else None, step, args.within)
    for name, p, s, run in variants:
        print(json.dumps({"sets": name, "pairs": int(len(p)), "set_count": int(len(np.unique(s))),
                          "wrong_pairs": int(wrong_pairs(run["true_positions"], p, s, step).sum()),
                          "affine_residual_2d_after": residual(run, cfg, p, s),
                          "povs": int(len(run["true_positions"])), "max_lattice_offset": lattice}),
              flush=True)


if __name__ == "__main__":
    main()
