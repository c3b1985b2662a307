"""Which path of the clocked agent stores a POV whose samples drift off one
eye pose (diagnostic; changes nothing the agent does).

Runs ``sensorispace reproduce --strategy naive`` (any of its arguments; the
configuration must set ``world.clock: rows``) with wrappers that note, for
every POV the agent's store receives: the path that added it (a reaction's
walk, a pending solution's walk, a POV kept from an undone reaction, the
start), the clock's rows at the walk's start and at the append, the changes
of the world between them and the world states they saw (ground truth:
``ClockedBody``), and the pose spread of its samples (``arm.forward``).
Writes beside the run's ``metrics.json``:

* ``clock_drift.json``: one record per POV stored;
* ``clock_drift_walks.npz``: the walk (start, target, each front's knots,
  Jacobians) of every POV whose spread exceeds 1e-3, and the lights of the
  world it was walked in, to replay it (``points_of_view.brief_loop_walks``);
* ``clock_drift_steps.npy``: per brief walk's closed loop, the largest
  distance its samples' projection moved them, their pose spread, and 1 if
  the walk kept it (the agent drops a loop with a sample moved farther than
  the walk's ``predictor_tol``: ``points_of_view.brief_loop_walks``), else 0.

Run as::

    nice -n 15 .venv/bin/python bench/clock_drift.py reproduce --strategy naive \\
        --config config/paper-clock.yaml --no-figures --quiet --out /tmp/clock_drift
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from bench.instrumented import run_instrumented  # noqa: E402

RECORDS: list = []
STACK: list = []
STATE: dict = {}


def _spread(samples: np.ndarray) -> float:
    from sensorispace_ros.core.arm import forward
    poses = forward(np.asarray(samples, float))
    centre = np.median(poses, axis=0)
    return float(np.max(np.abs(poses[:, :2] - centre[:2])))


def _dump(walk, samples, record) -> None:
    """Keep the walk that made a drifting POV: its start, knots, Jacobians, target."""
    gaps = np.linalg.norm(((walk.start - samples[0]) + np.pi) % (2 * np.pi) - np.pi, axis=1)
    p = int(np.argmin(gaps))
    path = walk.paths[p] if walk.paths[p] is not None else []
    DUMPS[f"pov{record['index']}_{len(RECORDS)}"] = {
        "start": walk.start[p], "target": walk.target[p], "samples": samples,
        "path": np.asarray(path, float),
        "forward": np.asarray(walk.branches[p][0], float),
        "backward": np.asarray(walk.branches[p][1], float),
        "jacobians": np.asarray(walk.jacobians_along[p], float),
        "state": record["state_start"], "queries": walk.queries[p]}


DUMPS: dict = {}
STEPS: list = []


def instrument() -> None:
    from sensorispace_ros.core import world_clock
    from sensorispace_ros.core.naive import points_of_view
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent as Agent

    init = world_clock.ClockedBody.__init__

    def body_init(self, *args, **kwargs):
        init(self, *args, **kwargs)
        STATE["body"] = self
    world_clock.ClockedBody.__init__ = body_init

    def tagged(name, method):
        def wrapper(self, *args, **kwargs):
            body = STATE.get("body")
            STACK.append((name, body.row if body is not None else -1))
            try:
                return method(self, *args, **kwargs)
            finally:
                STACK.pop()
        return wrapper

    for name in ("react", "begin_equality_pass", "walk_pending", "restore", "start",
                 "_sample_povs", "_walk_through", "_search", "_sweep_known"):
        setattr(Agent, name, tagged(name, getattr(Agent, name)))

    class Recorded(points_of_view.LoopWalk):
        def __init__(self, body, start, **kwargs):
            super().__init__(body, start, **kwargs)
            STATE["walk"] = self

        def project(self, samples, polish_iterations, sample_tol=np.inf, step_tol=np.inf,
                    checked=0):
            before = samples.copy()
            closed = np.flatnonzero([r == points_of_view.VALID for r in self.reason])
            out = super().project(samples, polish_iterations, sample_tol, step_tol, checked)
            if np.isfinite(step_tol) and polish_iterations:      # the brief walk
                for p in closed:
                    step = float(np.max(np.linalg.norm(samples[p, 1:] - before[p, 1:], axis=1)))
                    STEPS.append((step, _spread(samples[p]),
                                  float(self.reason[p] == points_of_view.VALID)))
            return out
    points_of_view.LoopWalk = Recorded

    append = points_of_view.PovStore.append

    def recorded(self, samples):
        index = append(self, samples)
        body = STATE.get("body")
        row = body.row if body is not None else -1
        start = STACK[-1][1] if STACK else -1
        walk_start = next((r for n, r in reversed(STACK) if n == "_walk_through"), start)
        changes = body.change_row if body is not None else np.zeros(0)
        crossed = [int(c) for c in changes if walk_start < c <= row]
        RECORDS.append({
            "index": int(index), "path": "/".join(n for n, _ in STACK),
            "walk_start_row": int(walk_start), "row": int(row),
            "changes_in_walk": crossed,
            "state_start": int(body.state_at(max(walk_start, 0))) if body is not None else -1,
            "state_end": int(body.state_at(max(row - 1, 0))) if body is not None else -1,
            "spread": _spread(samples), "extent": float(np.ptp(np.asarray(samples), 0).max()),
            "first": np.asarray(samples, float)[0].tolist()})
        if RECORDS[-1]["spread"] > 1e-3 and STATE.get("walk") is not None:
            _dump(STATE["walk"], np.asarray(samples, float), RECORDS[-1])
        return index
    points_of_view.PovStore.append = recorded


def main() -> None:
    def write(out: Path):
        out.mkdir(parents=True, exist_ok=True)
        (out / "clock_drift.json").write_text(json.dumps(RECORDS, indent=0))
        lights = STATE["body"].lights if "body" in STATE else []
        flat = {f"{k}.{n}": v for k, d in DUMPS.items() for n, v in d.items()}
        np.savez(out / "clock_drift_walks.npz", **flat,
                 **{f"lights{d['state']}": lights[d["state"]] for d in DUMPS.values()})
        steps = np.asarray(STEPS).reshape(-1, 3)
        np.save(out / "clock_drift_steps.npy", steps)
        worst = sorted(RECORDS, key=lambda r: -r["spread"])[:15]
        for r in worst:
            print({k: v for k, v in r.items() if k != "first"})

    run_instrumented(instrument, write)


if __name__ == "__main__":
    main()
