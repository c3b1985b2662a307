"""Why a noisy naive run stops growing: its sweep matches against ground truth.

Runs the naive agent (lockstep) on a body with imperfections no parameter
names (``ImperfectSensing``, as ``bench/noisy_naive.py``) and logs, at every
change and for every snapshot in the pool, which rows of the snapshot have
a partner among the POVs known now (a POV whose true pose is the row's moved
by the object's displacement, in the same light layout: a match that could
be made), which the agent matched (before and after its rank and averaged
tests) and whether those are right; and, for each provisional record
(``SnapshotMatching._hold_unconfirmed``), whether any later sweep could have
confirmed it::

    .venv/bin/python bench/noisy_growth.py --config config/paper.yaml --seed 0 --noise 1e-3

Prints one JSON line of totals, then the match test's view of the possible
matches it missed. Diagnostics only: nothing here is the agent's.
"""
from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.naive import confirm as confirm_mod
from sensorispace_ros.core.naive import run as naive_run
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
from imperfect_bodies import ImperfectSensing  # noqa: E402  (a test helper, shared)


REASONS: dict = {}
_JUDGE = confirm_mod._judge


def _judging(jac, residual, rank, whole, variances, limits, bounds, max_step):
    """``confirm._judge``, tallying in ``REASONS[stage]`` why states fail:
    what the noise leaves outside the Jacobian's range, the predicted pose
    error against ``max_error``, the pinning floor."""
    step, explained, settled = _JUDGE(jac, residual, rank, whole, variances, limits, bounds,
                                      max_step)
    u, singular, _ = np.linalg.svd(jac, full_matrices=False)
    along = np.einsum("bsk,bs->bk", u[:, :, :rank], residual)
    outside = np.sum(residual ** 2, axis=1) - np.sum(along ** 2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = np.sqrt(variances[0]) / singular[:, rank - 1]
    row = REASONS.setdefault(_STAGE[0], dict(judged=0, settled=0, outside=0, precision=0,
                                             only_precision=0, pinning=0, spread=[],
                                             max_error=[]))
    out_bad = ~(outside <= variances[0] * limits[0])
    prec_bad = ~(spread <= bounds[0])
    row["judged"] += len(residual)
    row["settled"] += int(settled.sum())
    row["outside"] += int(out_bad.sum())
    row["precision"] += int(prec_bad.sum())
    row["only_precision"] += int((prec_bad & ~out_bad).sum())
    row["pinning"] += int((~(singular[:, rank - 1] > bounds[1])).sum())
    row["spread"].extend(np.round(spread, 5).tolist())
    row["max_error"].append(float(bounds[0]))
    return step, explained, settled


confirm_mod._judge = _judging
_STAGE = ["other"]


class GrowthAgent(NaiveAgent):
    """``NaiveAgent`` that logs its sweeps, matches and held records."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.log: list[dict] = []
        self.sweeps: dict[int, np.ndarray] = {}
        self.held: list = []
        self.searched: list = []

    def _sweep_known(self):
        current, split = super()._sweep_known()
        self.sweeps[self._event] = np.array(current)
        self._entry = {"event": self._event, "pool": [s.event for s in self._pool],
                       "rows": [len(s.sensations) for s in self._pool],
                       "counts": [None if s.counts is None else np.array(s.counts)
                                  for s in self._pool], "K": len(current)}
        self.log.append(self._entry)
        return current, split

    def _match_snapshots(self, current, tree):
        out = super()._match_snapshots(current, tree)
        self._entry["raw"] = [(b.copy(), a.copy()) for b, a in out[0]]
        return out

    def _test_ranks(self, *args):
        out = super()._test_ranks(*args)
        self._entry["ranked"] = [(b.copy(), a.copy()) for b, a in out]
        return out

    def _verify_matches(self, matches):
        out = super()._verify_matches(matches)
        self._entry["verified"] = [(b.copy(), a.copy()) for b, a in out]
        return out

    def _anchor_requests(self, matches, rest_hits, rank_now, current=None):
        known, requests = super()._anchor_requests(matches, rest_hits, rank_now, current)
        if current is not None:
            self._entry["requests"] = [(r.snapshot, r.row) for r in requests]
            self._entry["snap_sens"] = [s.sensations.copy() for s in self._pool]
        return known, requests

    def _search(self, requests, current, tree, split_now):
        self._kinds = ["frontier" if r.row >= 0 else "anchor, confirmed" if r.neighbours
                       is not None else "anchor, unconfirmed" for r in requests]
        self._group = self._search_plan(requests, current)[0] if requests else None
        _STAGE[0] = "searches"
        found, new_povs, sensations = super()._search(requests, current, tree, split_now)
        _STAGE[0] = "other"
        tally = self.__dict__.setdefault("tally", {})
        for i, kind in enumerate(self._kinds):
            row = tally.setdefault(kind, dict(asked=0, solved=0, confirmed=0, held=0,
                                              found=0, new=0))
            row["asked"] += 1
            g = self._group[i]
            for stage in ("solved", "confirmed", "held"):
                row[stage] += int(g in self._stages.get(stage, {}))
            row["found"] += int(i in found)
            solved = self._stages.get("solved", {}).get(g)
            if solved is not None:
                self.searched.append((kind, self._event, self._pool[requests[i].snapshot].event,
                                      self._to_body(requests[i].anchor_motor_state),
                                      self._to_body(solved),
                                      g in self._stages.get("confirmed", {}),
                                      i in found))
            row["new"] += int(i in found and found[i][0] in new_povs)
        self._stages = {}
        return found, new_povs, sensations

    def _run_searches(self, unique_targets, owner, starts):
        out = super()._run_searches(unique_targets, owner, starts)
        self.__dict__.setdefault("_stages", {})["solved"] = dict(out[0])
        return out

    def _confirm_searched(self, *args):
        out = super()._confirm_searched(*args)
        self._stages["confirmed"] = dict(out)
        return out

    def _held_by_neighbours(self, solution, requests, group):
        out = super()._held_by_neighbours(solution, requests, group)
        if solution and requests:
            self._stages["held"] = dict(out)
        return out

    def _hold_unconfirmed(self, records, matches, known_comp, found_rest):
        before = {id(p) for p in getattr(self, "_provisional", [])}
        kept = super()._hold_unconfirmed(records, matches, known_comp, found_rest)
        for p in getattr(self, "_provisional", []):
            if id(p) not in before:
                self.held.append(p)
        self._entry["confirmed_held"] = len([r for r in kept if r.event != self._event])
        return kept


def _truth_partners(pose, rows_then, k_now, shift, tolerance):
    """For rows ``0..rows_then-1``: the index of the POV ``< k_now`` whose
    pose is the row's moved by ``shift`` (-1: none)."""
    target = pose[:rows_then].copy()
    target[:, :2] += shift
    d = np.linalg.norm(target[:, None, :2] - pose[None, :k_now, :2], axis=2)
    dth = np.abs((target[:, None, 2] - pose[None, :k_now, 2] + np.pi) % (2 * np.pi) - np.pi)
    d = np.hypot(d, dth)
    j = np.argmin(d, axis=1) if k_now else np.full(rows_then, -1)
    ok = d[np.arange(rows_then), j] <= tolerance if k_now else np.zeros(rows_then, bool)
    return np.where(ok, j, -1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--events", type=int, default=0, help="first changes only (0: all)")
    parser.add_argument("--save", default="", help="npz of the possible matches' distances")
    for name in ("noise", "quantum", "motor_noise"):
        parser.add_argument(f"--{name}", type=float, default=0.0)
    parser.add_argument("--set", action="append", default=[],
                        help="naive parameter override name=value")
    args = vars(parser.parse_args())
    cfg = config_mod.load_config(args.pop("config"))
    seed, events, save = args.pop("seed"), args.pop("events"), args.pop("save")
    overrides = dict(kv.split("=", 1) for kv in args.pop("set"))
    world = run_world(cfg, seed)
    if events:
        world.events = world.events[:events]
    naive = dict(cfg["naive"])
    for key, value in overrides.items():
        naive[key] = type(naive[key])(value)
    wrapper = functools.partial(ImperfectSensing, seed=seed + 7919,
                                **{k: v for k, v in args.items() if v})
    original = naive_run.NaiveAgent
    naive_run.NaiveAgent = GrowthAgent
    started = time.perf_counter()
    try:
        explored = naive_run.explore_naive(world, NaiveParams(**naive), body_wrapper=wrapper)
    finally:
        naive_run.NaiveAgent = original
    agent = explored.agent
    centers, layout = np.asarray(explored.centers), explored.layout
    tolerance = world.spacing / 4
    pose = world.arm.forward(agent.points_of_view[:, 0]) if agent._store.count else None
    totals = dict(events=len(agent.log), povs=agent._store.count, queries=agent.queries_total,
                  snapshot_pairs=0, same_layout=0, possible=0, possible_pairs=0, raw=0,
                  raw_right=0, ranked=0, ranked_right=0, verified=0, verified_right=0,
                  possible_found_raw=0, possible_found_verified=0, confirmed_held=0)
    missed_rows = []       # (distance to partner, to nearest other now, count)
    sd = agent.structure.noise if agent.structure is not None else 0.0
    for entry in agent.log:
        t = entry["event"]
        if "raw" not in entry:
            continue
        totals["confirmed_held"] += entry.get("confirmed_held", 0)
        current = agent.sweeps[t]
        for k, e in enumerate(entry["pool"]):
            totals["snapshot_pairs"] += 1
            if layout[t] != layout[e]:
                continue
            totals["same_layout"] += 1
            partner = _truth_partners(pose, entry["rows"][k], entry["K"], centers[t] - centers[e],
                                      tolerance)
            has = partner >= 0
            totals["possible"] += int(has.sum())
            totals["possible_pairs"] += int(has.any())
            for stage in ("raw", "ranked", "verified"):
                b, a = entry[stage][k]
                totals[stage] += len(b)
                totals[stage + "_right"] += int(np.sum(partner[b] == a))
            for stage in ("raw", "verified"):
                b, a = entry[stage][k]
                totals[f"possible_found_{stage}"] += int(np.sum(has[b] & (partner[b] == a)))
            sens = entry["snap_sens"][k]
            counts = entry["counts"][k]
            b_raw = set(entry["raw"][k][0].tolist())
            for i in np.flatnonzero(has):
                if i in b_raw:
                    continue
                d = np.linalg.norm(current - sens[i], axis=1)
                j = partner[i]
                others = np.delete(d, j)
                missed_rows.append((d[j], others.min() if len(others) else np.inf,
                                    1 if counts is None else counts[i]))
    # Held records: could any later sweep have confirmed them?
    could = 0
    for p in agent.held:
        rec = p.record
        rest_pose = pose[p.rest_pov]
        for entry in agent.log:
            t = entry["event"]
            if t <= rec.event or rec.anchor_event not in entry["pool"] or \
                    rec.event not in entry["pool"] or layout[t] != layout[rec.anchor_event]:
                continue
            target = rest_pose.copy()
            target[:2] += centers[t] - centers[rec.anchor_event]
            d = np.hypot(np.linalg.norm(pose[:entry["K"], :2] - target[:2], axis=1),
                         np.abs((pose[:entry["K"], 2] - target[2] + np.pi) % (2 * np.pi) - np.pi))
            if entry["K"] and d.min() <= tolerance:
                could += 1
                break
    totals["held"] = len(agent.held)
    totals["held_confirmable"] = could
    totals["noise_sd"] = sd
    totals["wall_s"] = round(time.perf_counter() - started, 1)
    print(json.dumps(totals))
    print(json.dumps({"requests by kind": getattr(agent, "tally", {})}))
    arm, by_kind = world.arm, {}
    for kind, t, e, anchor, solved, confirmed, kept in agent.searched:
        target = arm.forward(anchor[None])[0]
        target[:2] += centers[t] - centers[e]
        error = float(arm.pose_error(arm.forward(solved[None]), target[None])[0])
        right = error <= tolerance and layout[t] == layout[e]
        row = by_kind.setdefault(kind, dict(solved=0, solved_right=0, confirmed=0,
                                            confirmed_right=0, kept=0, kept_right=0))
        for stage, flag in (("solved", True), ("confirmed", confirmed), ("kept", kept)):
            row[stage] += int(flag)
            row[stage + "_right"] += int(flag and right)
    print(json.dumps({"searches against truth": by_kind}))
    for stage, row in REASONS.items():
        spread, limit = np.array(row.pop("spread")), np.array(row.pop("max_error"))
        finite = spread[np.isfinite(spread)]
        row["spread quantiles 10/50/90"] = np.round(np.percentile(finite, [10, 50, 90]), 4).tolist() \
            if len(finite) else []
        row["max_error last, median"] = [float(limit[-1]), float(np.median(limit))] \
            if len(limit) else []
        print(json.dumps({"confirm rounds, " + stage: row}))
    print(json.dumps({"separation": float(agent._store.separation()),
                      "max_pose_error": float(agent._max_pose_error()),
                      "repeats": int(agent._repeats), "weakest": agent.structure.weakest}))
    print(json.dumps({"motor states by stage": agent.queries_by_stage}))
    if missed_rows:
        m = np.array(missed_rows)
        print("missed possible matches:", len(m), "distance to partner quantiles 10/50/90",
              np.round(np.percentile(m[:, 0], [10, 50, 90]), 5).tolist(),
              "to nearest other", np.round(np.percentile(m[:, 1], [10, 50, 90]), 5).tolist(),
              "nearest other closer than partner", int(np.sum(m[:, 1] < m[:, 0])),
              "counts>1", int(np.sum(m[:, 2] > 1)))
        if save:
            np.save(save, m)


if __name__ == "__main__":
    main()
