"""Where a noisy naive run's wrong poses come from: each accepted
compensation tagged by its kind, against ground truth.

Runs the naive agent (lockstep) on a body with imperfections no parameter
names (``ImperfectSensing``, as ``bench/noisy_naive.py``) and prints, per
kind (a known POV matching an anchor, a searched anchor at rest, a searched
frontier row), how many compensations were accepted and how many lie more
than a quarter grid step from the pose their anchor asks for; then one line
per wrong compensation::

    .venv/bin/python bench/noisy_wrong.py --config config/paper.yaml --seed 0 --noise 1e-4

Diagnostics only: nothing here is the agent's.
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
from sensorispace_ros.core.naive import run as naive_run
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
from imperfect_bodies import ImperfectSensing  # noqa: E402  (a test helper, shared)


class TaggingAgent(NaiveAgent):
    """``NaiveAgent`` that keeps, beside each compensation record, its kind
    and its request's facts."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.tags: list[dict] = []
        self.match_log: list = []

    def _search(self, requests, current, tree, split_now):
        self._plan = self._search_plan(requests, current) if requests else None
        return super()._search(requests, current, tree, split_now)

    def _run_searches(self, unique_targets, owner, starts):
        out = super()._run_searches(unique_targets, owner, starts)
        self._outcome = (owner, starts, self._last_search)
        return out

    def _compensate(self, targets, starts, isolated):
        # Both passes of an averaged search end in the one outcome returned here.
        self._last_search = super()._compensate(targets, starts, isolated)
        return self._last_search

    def _truth(self, motor_states):
        """Noiseless sensations of ``motor_states`` (phases) in the world now."""
        inner = self._body._body
        return np.asarray(inner._sense(self._to_body(np.atleast_2d(motor_states))), float)

    def _rest_sensation(self, motor_state):
        self._true_rest = getattr(self, "_true_rest", {})
        self._true_rest[self._event] = self._truth(motor_state)[0]
        return super()._rest_sensation(motor_state)

    def _sweep_known(self):
        self._true_sweep = getattr(self, "_true_sweep", {})
        if self._store.count:
            self._true_sweep[self._event] = self._truth(self._store.samples[:, 0])
        return super()._sweep_known()

    def _anchor_requests(self, matches, rest_hits, rank_now, current=None):
        if current is not None:
            self._matches = matches
            for snap, (before, after) in zip(self._pool, matches):
                if len(before):
                    gap = np.nan
                    then = getattr(self, "_true_sweep", {}).get(snap.event)
                    now = self._true_sweep.get(self._event)
                    if then is not None and now is not None and before.max() < len(then):
                        gap = float(np.max(np.linalg.norm(then[before] - now[after], axis=1)))
                    self.match_log.append((self._event, snap.event, before.copy(), after.copy(),
                                           gap))
        return super()._anchor_requests(matches, rest_hits, rank_now, current)

    def _neighbourhood(self, r, x):
        """Motor distance of row ``r.row``'s POV to the nearest matched
        POV's curve in the snapshot, and of the solution ``x`` to that
        POV's partner's curve now (and the least over the 3 nearest)."""
        before, after = self._matches[r.snapshot]
        if not len(before):
            return {}
        curves = self._store.samples
        m_j = curves[r.row, 0]
        d_j = np.array([_curve_distance(m_j, curves[b]) for b in before])
        order = np.argsort(d_j)[:3]
        d_x = np.array([_curve_distance(x, curves[after[o]]) for o in order])
        return {"d_j": float(d_j[order[0]]), "d_x": float(d_x[0]),
                "d_x3": float(d_x.min()), "sep": float(self._store.separation())}

    def _search_facts(self, i):
        """Starts, accepted states and errors of request ``i``'s group."""
        group = self._plan[0]
        owner, starts, search = self._outcome
        mine = np.flatnonzero(owner == group[i])
        ok = mine[search.accepted[mine]]
        best = ok[np.argmin(search.sensory_error[ok])] if len(ok) else -1
        return {"starts": [self._to_body(starts[k]) for k in mine],
                "accepted": [self._to_body(search.motor_states[k]) for k in ok],
                "chosen_start": int(np.flatnonzero(mine == best)[0]) if best >= 0 else -1,
                "n_starts": len(mine)}

    def _compensation_records(self, known_comp, found_rest, requests, found):
        records, rest_choice = super()._compensation_records(known_comp, found_rest, requests,
                                                             found)
        tags = []
        for k in range(len(self._pool)):
            if k in known_comp:
                tags.append({"kind": "hit", "confirmed": bool(len(self._matches[k][0]))})
            elif k in found_rest:
                r = next(r for r in requests if r.snapshot == k and r.row < 0)
                i = next(i for i, q in enumerate(requests) if q.snapshot == k and q.row < 0)
                tags.append({"kind": "anchor", "count": r.count, **self._search_facts(i),
                             "confirmed": bool(len(self._matches[k][0]))})
            else:
                continue
        for i, r in enumerate(requests):
            if r.row >= 0 and i in found:
                taken = found[i][0] in self._matches[r.snapshot][1] or any(
                    q.snapshot == r.snapshot and q.row != r.row and j in found
                    and found[j][0] == found[i][0] for j, q in enumerate(requests))
                tags.append({"kind": "frontier", "count": r.count, "taken": bool(taken),
                             "start": None if r.start is None else self._to_body(r.start),
                             **self._search_facts(i), **self._neighbourhood(r, found[i][1])})
        assert len(tags) == len(records)
        for tag, rec in zip(tags, records):
            now = self._truth(self._phase.to_phase(rec.motor_state))[0]
            if tag["kind"] == "frontier":
                continue
            then = self._true_rest.get(rec.anchor_event)
            if then is not None:
                tag["true_gap"] = float(np.linalg.norm(now - then))
            state = self._phase.to_phase(rec.motor_state)
            eye = 1e-5 * np.eye(len(state))
            sensed = self._truth(np.vstack([state + eye, state - eye]))
            jac = (sensed[:len(state)] - sensed[len(state):]).T / 2e-5
            tag["singular"] = np.linalg.svd(jac, compute_uv=False)[:3].round(4).tolist()

        for tag, rec in zip(tags, records):
            tag["pov"] = rec.pov
            tag["record"] = rec
        self.tags.extend(tags)
        return records, rest_choice


def _curve_distance(point, curve):
    return float(np.min(np.linalg.norm((curve - point + np.pi) % (2 * np.pi) - np.pi, axis=1)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/smoke.yaml")
    parser.add_argument("--seed", type=int, default=0)
    for name in ("noise", "laplace", "relative", "quantum", "motor_noise", "dropout"):
        parser.add_argument(f"--{name}", type=float, default=0.0)
    parser.add_argument("--set", action="append", default=[],
                        help="naive parameter override name=value")
    args = vars(parser.parse_args())
    cfg = config_mod.load_config(args.pop("config"))
    seed = args.pop("seed")
    overrides = dict(kv.split("=", 1) for kv in args.pop("set"))
    world = run_world(cfg, seed)
    naive = dict(cfg["naive"])
    for key, value in overrides.items():
        naive[key] = type(naive[key])(value) if not isinstance(naive[key], bool) else \
            value.lower() in ("1", "true")
    params = NaiveParams(**naive)
    wrapper = functools.partial(ImperfectSensing, seed=seed + 7919,
                                **{k: v for k, v in args.items() if v})
    original = naive_run.NaiveAgent
    naive_run.NaiveAgent = TaggingAgent
    started = time.perf_counter()
    try:
        explored = naive_run.explore_naive(world, params, body_wrapper=wrapper)
    finally:
        naive_run.NaiveAgent = original
    agent = explored.agent
    centers = np.asarray(explored.centers)
    # Every compensation the agent found, whether it kept the record
    # (``kept``) or held it back unconfirmed (``_hold_unconfirmed``).
    kept_ids = {id(rec) for rec in agent.compensations}
    tolerance = world.spacing / 4
    arm = world.arm
    rows = []
    for tag in agent.tags:
        rec = tag["record"]
        target = arm.forward(rec.anchor_motor_state[None])[0]
        target[:2] += centers[rec.event] - centers[rec.anchor_event]
        pose = arm.forward(rec.motor_state[None])[0]
        error = float(arm.pose_error(pose[None], target[None])[0])
        row = {"event": rec.event, "anchor_event": rec.anchor_event, "kind": tag["kind"],
               "count": tag.get("count"), "pov": tag["pov"], "error": error,
               "layout_kept": explored.layout[rec.event] == explored.layout[rec.anchor_event],
               "true_gap": tag.get("true_gap"), "confirmed": tag.get("confirmed"),
               "singular": tag.get("singular"), "kept": id(rec) in kept_ids,
               "taken": tag.get("taken")}
        if tag.get("start") is not None:
            start_pose = arm.forward(tag["start"][None])[0]
            row["from_start"] = float(np.linalg.norm(pose[:2] - start_pose[:2]))
            row["start_error"] = float(arm.pose_error(start_pose[None], target[None])[0])
        if "accepted" in tag:
            errs = [float(arm.pose_error(arm.forward(a[None]), target[None])[0])
                    for a in tag["accepted"]]
            row["alt_errors"] = [round(e, 3) for e in errs]
            row["chosen_start"] = tag["chosen_start"]
            row["n_starts"] = tag["n_starts"]
            for key in ("d_j", "d_x", "d_x3", "sep"):
                if key in tag:
                    row[key] = tag[key]
            row["motor_jump"] = float(np.linalg.norm(
                (rec.motor_state - tag["starts"][tag["chosen_start"]] + np.pi) % (2 * np.pi)
                - np.pi)) if tag["chosen_start"] >= 0 else None
        rows.append(row)
    summary = {}
    held = [r for r in rows if not r["kept"]]
    later = [r for r in rows if r["kept"] and r["kind"] != "frontier" and not r["confirmed"]]
    summary["unconfirmed, recorded once a later sweep confirmed it"] = (
        len(later), sum(r["error"] > tolerance for r in later))
    summary["held back (not recorded)"] = (len(held), sum(r["error"] > tolerance for r in held))
    summary["recorded, wrong, across a redistribution"] = (
        sum(r["kept"] for r in rows), sum(r["kept"] and r["error"] > tolerance for r in rows),
        sum(r["kept"] and not r["layout_kept"] for r in rows))
    for kind in ("hit", "anchor", "frontier"):
        of = [r for r in rows if r["kind"] == kind]
        summary[kind] = (len(of), sum(r["error"] > tolerance for r in of))
        known = [r for r in of if r["pov"] >= 0 and agent.pov_events[r["pov"]] != r["event"]]
        summary[kind + " on a POV known before (right, wrong)"] = (
            sum(r["error"] <= tolerance for r in known), sum(r["error"] > tolerance for r in known))
        taken = [r for r in of if r.get("taken")]
        summary[kind + " on a POV another row of its snapshot is paired with (right, wrong)"] = (
            sum(r["error"] <= tolerance for r in taken), sum(r["error"] > tolerance for r in taken))
        summary[kind + " with no POV (right, wrong)"] = (
            sum(r["pov"] < 0 and r["error"] <= tolerance for r in of),
            sum(r["pov"] < 0 and r["error"] > tolerance for r in of))
    anchors = [r for r in rows if r["kind"] == "anchor"]
    summary["anchor of a confirmed snapshot"] = (
        sum(bool(r["confirmed"]) for r in anchors),
        sum(bool(r["confirmed"]) and r["error"] > tolerance for r in anchors))
    hits = [r for r in rows if r["kind"] == "hit"]
    summary["hit of an unconfirmed snapshot"] = (
        sum(not r["confirmed"] for r in hits),
        sum(not r["confirmed"] and r["error"] > tolerance for r in hits))
    summary["anchor of an unconfirmed snapshot"] = (
        sum(not r["confirmed"] for r in anchors),
        sum(not r["confirmed"] and r["error"] > tolerance for r in anchors))
    print(json.dumps({"povs": agent._store.count, "queries": agent.queries_total,
                      "wrong_by_kind": summary, "wall_s": round(time.perf_counter() - started, 1),
                      "spacing": world.spacing}))
    for r in rows:
        if r["error"] > tolerance:
            print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v)
                              for k, v in r.items()}))
    for kind in ("hit", "anchor"):
        for ok in (True, False):
            weak = [r["singular"][-1] for r in rows if r["kind"] == kind and r.get("singular")
                    and (r["error"] <= tolerance) == ok]
            if weak:
                print(kind, "right" if ok else "wrong", "weakest singular value quantiles "
                      "0/10/50/90/100", np.round(np.percentile(weak, [0, 10, 50, 90, 100]),
                                                 4).tolist())
    for kind in ("anchor", "frontier"):
        for ok in (True, False):
            of = [r for r in rows if r["kind"] == kind and (r["error"] <= tolerance) == ok]
            if of:
                jumps = np.array([r["motor_jump"] for r in of if r.get("motor_jump") is not None])
                chosen = np.bincount([r["chosen_start"] for r in of if r["chosen_start"] >= 0])
                print(kind, "right" if ok else "wrong", "chosen start counts", chosen.tolist(),
                      "motor jump quantiles 50/90/99/max",
                      np.round(np.percentile(jumps, [50, 90, 99, 100]), 3).tolist())
    pose = arm.forward(agent.points_of_view[:, 0])
    wrong_matches, n_matches, wrong_by_lag, right_gaps = 0, 0, {}, []
    for event, snap_event, before, after, gap in agent.match_log:
        shift = centers[event] - centers[snap_event]
        err = np.linalg.norm(pose[after, :2] - pose[before, :2] - shift, axis=1)
        bad = int(np.sum(err > tolerance))
        wrong_matches += bad
        n_matches += len(before)
        if bad:
            print(json.dumps({"wrong matches at": event, "snapshot": snap_event,
                              "matched": len(before), "wrong": bad, "true_gap": gap,
                              "median error": round(float(np.median(err)), 3)}))
        if not bad and np.isfinite(gap):
            right_gaps.append(gap)
        lag = min(event - snap_event, 5)
        wrong_by_lag[lag] = wrong_by_lag.get(lag, 0) + bad
    if right_gaps:
        print("right match logs: largest true gap quantiles 50/90/99/max",
              np.round(np.percentile(right_gaps, [50, 90, 99, 100]), 5).tolist())
    print(json.dumps({"sweep matches": n_matches, "wrong": wrong_matches,
                      "wrong by lag (5: 5+)": wrong_by_lag}))
    front = [r for r in rows if r["kind"] == "frontier" and "d_j" in r]
    if front:
        np.save("/tmp/nw_front.npy", np.array([[r["error"], r["d_j"], r["d_x"], r["d_x3"],
                                                r["sep"]] for r in front]))
    right = [r for r in rows if r["kind"] == "frontier" and r["error"] <= tolerance]
    if right:
        d = np.array([r["from_start"] for r in right])
        print("right frontier: distance from start pose, median %.3f p95 %.3f max %.3f" % (
            np.median(d), np.percentile(d, 95), d.max()))


if __name__ == "__main__":
    main()
