"""Where a naive run on a MuJoCo body goes wrong and where its time goes
(docs/mujoco.md, docs/benchmarks.md "A MuJoCo body").

    .venv/bin/python -m bench.mujoco_naive --config config/mujoco-smoke.yaml [--seed S]
    .venv/bin/python -m bench.mujoco_naive --config config/mujoco-arm.yaml --views 4000
    .venv/bin/python -m bench.mujoco_naive --config config/mujoco-arm.yaml --graph-against DIR

Runs the naive agent through the configuration's world (lockstep, as
``sensorispace reproduce``), then joins each accepted compensation with
ground truth: its kind (a known POV matching an anchor, a search for a
resting anchor, a search for a frontier row of a sweep), its pose error
against the pose its anchor asks for, and whether it spans a state change;
for a searched one also what the agent knew of it (whether a match confirmed
its snapshot, its matched neighbours' motor distances to the asked row and
to the end, over the POVs' separation, and how far the end senses from the
target, over what two sensings differ by at its measured noise).
Prints JSON: the evaluator's headline numbers, wrong compensations by kind
with their errors, every searched compensation, the rows and seconds of
each stage, the body's rendering time per frame, the requests searched (by
their target's distance to the POVs known then and its place against the
paper strategy's positions: nearer the base, farther, between) with how
many ended and on a POV, and the paper's positions no POV reached with the
requests that asked for each. ``--views N`` runs no agent: it renders N views
(joint states about the start, sd 1 rad, the object at seeded grid
positions) and prints how many of them show almost nothing (few pixels
above 20 gray levels), and the CPU time per frame. ``--graph-against DIR``
runs the configuration's seed through the graph (its nodes in this process)
and compares what it gives with DIR, the output of ``sensorispace
reproduce --strategy naive`` on the same configuration and seed.
"""
from __future__ import annotations

import argparse
import json
import time
from collections import Counter

import numpy as np


def _run(cfg: dict, seed: int):
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.body import SensingOnly
    from sensorispace_ros.core.naive.agent import NaiveAgent
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.naive.run import NaiveExploration, summarize_naive
    from sensorispace_ros.core.world import REDISTRIBUTION

    world = run_world(cfg, seed)
    body = world.body(lights=world.initial_lights)
    agent = NaiveAgent(SensingOnly(body), NaiveParams(**cfg["naive"]))
    searches = _log_searches(agent, body)
    centers, layout, kinds = [np.asarray(world.initial_center, float)], [0], ["initial"]
    requests = _log_requests(agent, world, centers)
    started = time.perf_counter()
    reaction = agent.start(world.m0, seed=world.seed)
    rests, trace = [reaction.rest_motor_state], [_traced(reaction, "initial", body)]
    for event in world.events:
        body.set_lights(event.lights)
        centers.append(np.asarray(event.center, float))
        layout.append(layout[-1] + (event.kind == REDISTRIBUTION))
        kinds.append(event.kind)
        reaction = agent.react(body.sense_at_rest()[0])
        rests.append(reaction.rest_motor_state)
        trace.append(_traced(reaction, event.kind, body))
    explored = NaiveExploration(agent, centers, layout, kinds, time.perf_counter() - started, 0.0)
    return (world, body, summarize_naive(explored), np.asarray(rests), started, trace, searches,
            requests)


def _log_searches(agent, body) -> list:
    """Wraps ``agent._search``: per accepted search, what the agent knew of
    it (its snapshot's matches, the nearest matched neighbour's reach over
    the POVs' separation, the POVs known) and how far its end senses from
    its target, in the agent's measured noise (sensed without counting as
    the agent's)."""
    from sensorispace_ros.core.naive.neighbours import curve_distances

    log = []
    search = agent._search

    def wrapped(requests, current, tree, split_now):
        found, new_povs, new_sensations = search(requests, current, tree, split_now)
        # The cached separation, read without refreshing it (a refresh at
        # another moment would change what the agent decides later).
        separation = agent._store._separation[1] or float("nan")
        for i, (pov, motor) in found.items():
            r = requests[i]
            frames = body.renderer.frames
            image = body._look(np.asarray(agent._to_body(motor), float)[None])[0][0]
            body.renderer.frames = frames
            d2 = float(np.sum((image.astype(float) - r.target) ** 2))
            reach = r.neighbours.reach if r.neighbours is not None else np.zeros(0)
            near = curve_distances(motor, agent._store.samples[r.neighbours.after]) \
                if r.neighbours is not None else np.zeros(0)
            log.append({"event": agent._event, "snapshot_event": agent._pool[r.snapshot].event,
                        "row": int(r.row), "motor": np.asarray(agent._to_body(motor), float),
                        "confirmed": r.neighbours is not None,
                        "reach_over_separation": [round(float(x / separation), 2)
                                                  for x in reach],
                        "near_over_separation": [round(float(x / separation), 2)
                                                 for x in near],
                        "povs_known": int(agent._store.count),
                        "residual_over_noise": round(d2 / (2 * agent.structure.noise ** 2
                                                           * body.n_sensors), 2),
                        "count": int(r.count), "pov": int(pov)})
        return found, new_povs, new_sensations

    agent._search = wrapped
    return log


def _log_requests(agent, world, centers: list) -> list:
    """Wraps ``agent._anchor_requests`` and ``agent._search``: per request the
    agent searched, its event, kind (``anchor``: a snapshot's rest;
    ``frontier``: a row of its sweep), the sensor position it asks for (the
    anchor's or the row's position moved as the object moved since the
    snapshot), that target's distance to the nearest POV known then, whether
    a search ended and whether the end is a POV (ground truth: the forward
    model, not counted as the agent's)."""
    log, asked = [], {}
    requests_of, search = agent._anchor_requests, agent._search

    def position(motor):
        return world.arm.forward(np.asarray(agent._to_body(motor), float)[None])[0][:2]

    def wrapped_requests(matches, rest_hits, rank_now, current=None):
        known_comp, requests = requests_of(matches, rest_hits, rank_now, current)
        t = agent._event
        known = np.array([position(m) for m in agent._store.samples[:agent._store.count, 0]])
        asked[t] = []
        for r in requests:
            snap = agent._pool[r.snapshot]
            source = agent._store.samples[r.row, 0] if r.row >= 0 else snap.rest_motor_state
            target = position(source) + centers[t] - centers[snap.event]
            nearest = float(np.min(np.hypot(*(known - target).T))) if len(known) else np.inf
            asked[t].append((r.row >= 0, target, nearest))
        return known_comp, requests

    def wrapped_search(requests, current, tree, split_now):
        found, new_povs, new_sensations = search(requests, current, tree, split_now)
        for i, (frontier, target, nearest) in enumerate(asked.pop(agent._event, [])):
            log.append({"event": agent._event, "frontier": frontier, "target": target,
                        "nearest_known": nearest, "ended": i in found,
                        "pov": i in found and found[i][0] >= 0})
        return found, new_povs, new_sensations

    agent._anchor_requests, agent._search = wrapped_requests, wrapped_search
    return log


def _request_summary(requests: list, world, spacing: float, true_positions: np.ndarray) -> dict:
    """The searched requests by the target's distance to the nearest known POV
    (in grid steps) and by where the target lies against the paper strategy's
    positions (``inside``: nearer the base than all of them; ``beyond``:
    farther than all); and the paper's positions no POV reached, each with
    the requests that asked for it (event, kind, whether a search ended and
    on a POV)."""
    from scipy.spatial import cKDTree

    from sensorispace_ros.evaluation.ground_truth import paper_compensated_positions

    paper = paper_compensated_positions(world)
    radius = np.hypot(*paper.T)
    tolerance = 0.25 * spacing
    rows = []
    for q in requests:
        r = float(np.hypot(*q["target"]))
        where = ("inside" if r < radius.min() - tolerance
                 else "beyond" if r > radius.max() + tolerance else "between")
        steps = q["nearest_known"] / spacing
        reach = next(label for limit, label in ((0.2, "<=0.2"), (1.2, "0.2-1.2"),
                                                (2.4, "1.2-2.4"), (np.inf, ">2.4"))
                     if steps <= limit)
        rows.append(("frontier" if q["frontier"] else "anchor", where, reach, q))
    table = Counter((k, w, s) for k, w, s, _ in rows)
    ended = Counter((k, w, s) for k, w, s, q in rows if q["ended"])
    povs = Counter((k, w, s) for k, w, s, q in rows if q["pov"])
    missed = []
    if len(true_positions):
        distance, _ = cKDTree(true_positions).query(paper, k=1)
        for position in paper[distance > tolerance]:
            asked = [f"{q['event']}:{'f' if q['frontier'] else 'a'}:"
                     f"{'pov' if q['pov'] else 'ended' if q['ended'] else 'no'}"
                     for q in requests if np.hypot(*(q["target"] - position)) <= tolerance]
            missed.append([np.round(position, 2).tolist(), asked])
    return {
        "requests_columns": ["kind", "target", "nearest known POV (grid steps)", "requests",
                             "ended", "ended on a POV"],
        "requests": [[*key, n, ended[key], povs[key]] for key, n in sorted(table.items())],
        "paper_positions_missed": missed,
    }


def _traced(reaction, kind: str, body) -> dict:
    """One event: its kind, compensations, new POVs and rows, and per
    compensation what its image holds (pixels above 20 gray levels, the
    brightest), sensed without counting as the agent's."""
    lit = []
    for record in reaction.compensations:
        frames = body.renderer.frames
        image = body._look(np.asarray(record.motor_state, float)[None])[0][0]
        body.renderer.frames = frames
        lit.append([int(np.sum(image > 20)), int(image.max())])
    return {"kind": kind[:5], "comp": len(reaction.compensations),
            "new": len(reaction.new_pov_ids), "rows": int(reaction.queries), "lit": lit}


def _kinds(agent, rests: np.ndarray) -> list[str]:
    """Each record's kind: ``known`` (a known POV matched the anchor),
    ``anchor`` (searched, the snapshot's resting anchor), ``frontier``
    (searched, a row of the snapshot's sweep)."""
    out = []
    for record in agent.compensations:
        if not record.searched:
            out.append("known")
        elif np.allclose(record.anchor_motor_state, rests[record.anchor_event]):
            out.append("anchor")
        else:
            out.append("frontier")
    return out


def diagnose(cfg: dict, seed: int) -> dict:
    from sensorispace_ros.core import arm
    from sensorispace_ros.evaluation.naive import evaluate_naive_run

    world, body, result, rests, started, trace, searches, requests = _run(cfg, seed)
    wall = time.perf_counter() - started
    agent = result.agent
    evaluated = evaluate_naive_run(result, world).metrics
    spacing = float(world.spacing)
    tolerance = 0.25 * spacing
    records = agent.compensations
    errors, splits = [], []
    for record in records:
        target = world.arm.forward(np.asarray(record.anchor_motor_state, float)[None])[0]
        center_then = result.exploration.centers[record.anchor_event]
        center_now = result.exploration.centers[record.event]
        target[:2] += center_now - center_then
        reached = world.arm.forward(np.asarray(record.motor_state, float)[None])[0]
        errors.append(float(arm.pose_error(reached[None], target[None])[0]))
        splits.append((float(np.hypot(*(reached[:2] - target[:2]))),
                       float(abs(arm.wrap_angle(reached[2] - target[2])))))
    errors = np.asarray(errors)
    kinds = _kinds(agent, rests)
    layout = np.asarray(result.exploration.layout)
    crossing = [bool(layout[r.event] != layout[r.anchor_event]) for r in records]
    lit = [pair for step in trace for pair in step["lit"]]
    wrong = [{"event": r.event, "anchor_event": r.anchor_event, "kind": k, "lit": lt,
              "error": round(float(e), 4), "position_error": round(sp[0], 4),
              "heading_error": round(sp[1], 4), "across_state_change": c, "pov": r.pov}
             for r, k, e, c, lt, sp in zip(records, kinds, errors, crossing, lit, splits)
             if e > tolerance]
    for w, r in ((w, r) for w in wrong for r in records
                 if r.event == w["event"] and r.anchor_event == w["anchor_event"]
                 and r.pov == w["pov"]):
        w["search"] = [{k: v for k, v in s.items() if k != "motor"} for s in searches
                       if s["event"] == r.event and np.allclose(s["motor"], r.motor_state)]
    # Every searched compensation: kind, error, and what the agent knew of it.
    searched = []
    for r, k, e, c in zip(records, kinds, errors, crossing):
        for s in (s for s in searches if r.searched and s["event"] == r.event
                  and np.allclose(s["motor"], r.motor_state)):
            searched.append([k[0], round(float(e), 4), int(c), s["residual_over_noise"],
                             s["povs_known"], int(s["confirmed"]), s["reach_over_separation"],
                             s["near_over_separation"], s["count"]])
            break
    by_kind = {kind: {"accepted": n, "wrong": sum(w["kind"] == kind for w in wrong)}
               for kind, n in Counter(kinds).items()}
    keys = ("naive.pose_rank", "naive.pov_dim", "naive.space_dim", "pov.count",
            "naive.coverage_of_paper_positions", "naive.wrong_poses",
            "naive.state_changes_accepted", "naive.pose_error_median", "naive.pose_error_p95",
            "naive.queries_total", "naive.queries_total_per_pov", "naive.queries_per_pov")
    return {
        "seed": seed, "wall_s": round(wall, 1), "grid_step": spacing,
        "metrics": {k: evaluated.get(k) for k in keys},
        "compensations_by_kind": by_kind,
        "wrong": wrong,
        "searched_columns": ["kind", "error", "across_state_change", "residual_over_noise",
                             "povs_known", "confirmed", "reach_over_separation",
                             "near_over_separation", "target_sensings"],
        "searched": searched,
        "rows_by_stage": agent.queries_by_stage,
        "seconds_by_stage": {k: round(v, 1) for k, v in agent.seconds_by_stage.items()},
        "frames": int(body.renderer.frames),
        "render_ms_per_frame": round(1e3 * body.render_seconds / max(body.renderer.frames, 1), 3),
        "render_s": round(body.render_seconds, 1),
        "events": [f"{t}:{step['kind']}:c{step['comp']}:n{step['new']}:r{step['rows']}"
                   for t, step in enumerate(trace)],
        **_request_summary(requests, world, spacing,
                           world.arm.forward(agent.points_of_view[:, 0])[:, :2]
                           if len(agent.points_of_view) else np.zeros((0, 2))),
    }


def view_content(cfg: dict, n_views: int, seed: int) -> dict:
    """What ``n_views`` views hold: pixels above 20 gray levels per view, and CPU ms per frame."""
    from sensorispace_ros.bodies import run_world
    from sensorispace_ros.core.seeding import rng_for

    world = run_world(cfg, seed)
    body = world.body(lights=world.initial_lights)
    rng = rng_for(seed, "bench_views")
    lit, cpu, batch = [], 0.0, 200
    for _ in range(max(1, n_views // batch)):
        body.set_lights(world.grid[rng.integers(len(world.grid))] + world.initial_offsets)
        states = world.m0 + rng.normal(0.0, 1.0, size=(batch, len(world.m0)))
        started = time.process_time()
        images = body.sense(states)
        cpu += time.process_time() - started
        lit.append(np.sum(images > 20, axis=1))
    lit = np.concatenate(lit)
    return {"model": str(cfg["mujoco"]["model"]), "views": int(len(lit)),
            "share_lit_at_most_10": round(float(np.mean(lit <= 10)), 3),
            "share_lit_at_most_30": round(float(np.mean(lit <= 30)), 3),
            "median_lit": float(np.median(lit)),
            "cpu_ms_per_frame": round(1e3 * cpu / len(lit), 3)}


def graph_against(config_path: str, offline_dir: str, domain_id: int = 93) -> dict:
    """The graph's run (in one process) against reproduce's ``arrays.npz`` in ``offline_dir``."""
    import tempfile
    from pathlib import Path

    from sensorispace_ros.graph import in_process

    out = Path(tempfile.mkdtemp(prefix="mujoco-graph-"))
    started = time.perf_counter()
    result = in_process.run_graph_in_process(config_path, domain_id, out, timeout_s=5400)
    graph = np.load(out / "representation.npz")
    offline = np.load(Path(offline_dir) / "arrays.npz")
    agent = result["nodes"]["agent"].agent
    equal = {key: bool(graph[key].shape == offline[key].shape
                       and np.array_equal(graph[key], offline[key]))
             for key in ("povs", "pairs", "set_ids", "hausdorff", "embedding_2d_iterations",
                         "embedding_3d_iterations") if key in offline and key in graph}
    return {"wall_s": round(time.perf_counter() - started, 1), "povs": int(len(graph["povs"])),
            "compensated": int(agent.compensated), "queries_total": int(agent.queries_total),
            "equal_to_offline": equal, "results": str(out)}


def main(argv=None) -> None:
    from sensorispace_ros.config import load_config, parse_overrides

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="config/mujoco-smoke.yaml")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one parameter (YAML value), e.g. world.grid_count=4")
    parser.add_argument("--views", type=int, default=0, metavar="N",
                        help="render N views and count those of almost nothing (no agent)")
    parser.add_argument("--graph-against", default="", metavar="DIR",
                        help="run through the graph and compare with reproduce's output DIR")
    args = parser.parse_args(argv)
    if args.graph_against:
        print(json.dumps(graph_against(args.config, args.graph_against), indent=1))
        return
    cfg = load_config(args.config, parse_overrides(args.set) or None)
    seed = int(cfg["seed"] if args.seed is None else args.seed)
    if args.views:
        print(json.dumps(view_content(cfg, args.views, seed), indent=1))
        return
    print(json.dumps(diagnose(cfg, seed), indent=1))


if __name__ == "__main__":
    main()
