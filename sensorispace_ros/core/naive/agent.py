"""The naive agent: explores by compensating, from the sensorimotor flow alone.

``NaiveAgent`` is event driven so the ROS agent node can wrap it unchanged:
``start(m0)`` once, then ``react(passive_sensation)`` after every change of
the environment. Its only access to the world is ``body.sense`` (motor
states in, their sensations out, in the current static environment): no
forward model, no displacement, no event kind, no arm, retina or world.

Anchors. The paper compensates toward "the pose at the last successful
compensation plus the displacement since", knowing the displacement. The
agent only has sensations, and a remembered sensation stays a valid target
only until the object's lights are redistributed, which the agent cannot
tell from an out-of-reach translation (both make compensation fail).
Re-anchoring on every failure would keep one target at a time and cover
only a fraction of the reachable positions. Here the agent keeps a small
pool of *snapshots* (``anchors``): after each event it records, in the
environment of that event, the sensation at its resting arm (the anchor)
and the sensation of one sample of every known POV (a sweep). At the next
event it sweeps the known POVs again (one ``sense`` call) and

* matches old sweeps with the new one: POV j' now sensing what POV j sensed
  at snapshot time means pose(j') - pose(j) is the object's displacement
  since then. One such match (unique, full pose rank) *confirms* the snapshot: no
  redistribution since. The matched changes of a snapshot form an equality
  set (simulation 2), and a known POV that matches an anchor compensates it
  without any search;
* searches (Levenberg-Marquardt, batched) for the anchors of confirmed
  snapshots, and for a few anchors of recent unconfirmed ones while few POVs
  are known (how it recovers after a redistribution: an unconfirmed
  snapshot with many POVs is from before a redistribution or a translation
  so long that its anchor's target is out of reach anyway);
* searches for "frontier" rows of the most recent confirmed snapshot: POVs
  that did not match but sensed like ones that did; their targets are the
  unknown positions next to the known ones, moved by the displacement;
* samples the POV of every new compensating motor state (batched walk).

Every anchor is recorded at a resting arm that is the start or a
compensating state, and compensation keeps the eye's orientation, so every
accepted POV is a spatial relative of the start's (the set {M*}_0). A
compensating state sensing what a known POV senses is that POV (dedupe).
The passive sensation given to ``react`` is checked, not used (the sweep
senses the resting POV again).

Before anything else ``start`` measures the body's structure (``structure``):
the pose rank, the POV dimension and the sensory gain every sensation
tolerance is scaled by. The agent works in phases (each joint's period, as
the body's description states it, is 2 pi); it reports in the body's units.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.core.naive.anchors import Snapshot, SnapshotMatching
from sensorispace_ros.core.naive.equality_sets import (RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN,
    EqualitySetCollection, EqualitySetSweep, check_pose_rank, finite_rows)
from sensorispace_ros.core.naive.frontier import FrontierChoice
from sensorispace_ros.core.naive.lattice_sets import ImpliedSets
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.points_of_view import PovStore
from sensorispace_ros.core.naive.pov_relaxation import RelaxedPOVs
from sensorispace_ros.core.naive.records import EQUALITY_PASS, CompensationRecord, Reaction
from sensorispace_ros.core.naive.records import STAGES, NaiveAgentRecords  # noqa: F401  (re-exported)
from sensorispace_ros.core.naive.searching import SearchAndSample
from sensorispace_ros.core.naive.sense_memory import CountingBody, MotorPhase
from sensorispace_ros.core.naive.noise import (averaged_search_params, averaging_repeats,
    finite_difference_step, jacobian_noise, measure_body, noise_residual, noise_step)
from sensorispace_ros.core.naive.start import choose_start
from sensorispace_ros.core.naive.structure import BodyStructure, Tolerances

EXPLORING = "exploring"


class NaiveAgent(ImpliedSets, RelaxedPOVs, SnapshotMatching, FrontierChoice, SearchAndSample):
    """Event-driven naive explorer (see the module docstring).

    ``body`` needs ``sense(motor_states (B, M)) -> (B, S)``, ``n_motors`` and
    ``n_sensors``, and may state its joints' periods in ``description``
    (a ``BodyDescription``; without one every joint is a hinge in radians);
    ``sense`` is called from the thread that calls ``start``/
    ``react`` and may be a round trip to another process. Every ``start``/
    ``react`` ends with a one-row command: the arm rests at
    ``rest_motor_state``. The policy draws no random numbers: the same
    sensations give the same run. ``params`` are the given parameters until
    ``start``, then those sized from the noise it measured
    (``noise.measure_body``; unchanged on a noiseless body).
    """
    _noise_measured = None      # called (center, noise) once the start measured its noise
    _partial_recall = True      # a call senses only its rows not sensed since the change

    def __init__(self, body, params: NaiveParams | None = None):
        self.params = params if params is not None else NaiveParams()
        if not isinstance(self.params, NaiveParams):
            raise ValueError(f"params: must be a NaiveParams, got {type(params).__name__}")
        for name in ("n_motors", "n_sensors"):
            value = getattr(body, name, None)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"body: must expose a positive integer {name}, got {value!r}")
        if not callable(getattr(body, "sense", None)):
            raise ValueError("body: must expose sense(motor_states)")
        description = getattr(body, "description", None)
        if description is None:
            description = BodyDescription.revolute(int(body.n_motors), int(body.n_sensors))
        if not isinstance(description, BodyDescription) or \
                description.n_motors != int(body.n_motors):
            raise ValueError(f"body: description must be a BodyDescription of {body.n_motors} "
                             f"joints, got {description!r}")
        self.description = description
        self._phase = MotorPhase(description.periods)
        self._body = CountingBody(body, bool(self.params.remember_sensations), self._phase,
                                  self.params.lost_row_retries, self._partial_recall)
        self.n_motors = self._body.n_motors
        self.structure: BodyStructure | None = None     # measured by start()
        self._tol: Tolerances | None = None
        self._fd_step = self.params.fd_step     # every Jacobian's step, sized by start()
        self._repeats = 1                       # sensings averaged per anchor, sized by start()
        self._noisy = False                     # noise sized the tolerances (start())
        self._store = PovStore(self.params.n_samples, self.n_motors)
        # One motor state of every POV whose walk came back split (remember_split_povs).
        self._split_states = np.zeros((0, self.n_motors))
        self.split_walks_skipped = 0
        self.pov_queries: list[int] = []           # walk queries of each POV
        self.pov_events: list[int] = []            # the agent's event that found each POV
        self.compensation_queries: list[int] = []  # per event with an accepted compensation
        self.compensations: list[CompensationRecord] = []
        self._sets = EqualitySetCollection(min_pairs=2)
        self._pool: list[Snapshot] = []
        self._provisional: list = []     # records a later sweep must confirm (_hold_unconfirmed)
        self._event = -1
        self._rest: np.ndarray | None = None
        self._rest_pov = -1
        self.phase = EXPLORING
        self._sweep: EqualitySetSweep | None = None
        self.events_compensated = 0
        self._frontier_success = 1.0     # moving average of frontier searches finding a new POV

    # ------------------------------------------------------------------ API

    @property
    def points_of_view(self) -> np.ndarray:
        """``(P, N, M)`` samples of every POV found so far (a copy, body's units)."""
        return self._to_body(self._store.samples)

    @property
    def split_motor_states(self) -> np.ndarray:
        """``(Q, M)`` one motor state of every POV whose walk came back split
        (``remember_split_povs``; a copy, in the body's units)."""
        return self._to_body(self._split_states)

    @property
    def compensated(self) -> int:
        """Events (changes of the environment) with an accepted compensation."""
        return self.events_compensated

    @property
    def n_samples(self) -> int:
        """Samples kept per POV: ``n_samples``, or ``n_samples_surface`` when
        the POVs are surfaces (``start`` measures which)."""
        surface = self.structure is not None and self.structure.pov_dim == 2
        return self.params.n_samples_surface if surface else self.params.n_samples

    @property
    def rest_motor_state(self) -> np.ndarray | None:
        return None if self._rest is None else self._to_body(self._rest)

    @property
    def queries_total(self) -> int:
        return self._body.total_rows

    @property
    def calls_total(self) -> int:
        return self._body.total_calls

    @property
    def queries_by_stage(self) -> dict:
        return dict(self._body.rows)

    @property
    def calls_by_stage(self) -> dict:
        return dict(self._body.calls)

    @property
    def remembered_by_stage(self) -> dict:
        """Calls answered from what was sensed since the last change
        (``remember_sensations``), per stage: not sent, not in ``calls_by_stage``."""
        return dict(self._body.remembered)

    @property
    def recalled_by_stage(self) -> dict:
        """Rows of sent calls answered from memory, per stage: not in ``queries_by_stage``."""
        return dict(self._body.recalled)

    @property
    def seconds_by_stage(self) -> dict:
        """Wall time per stage (sense calls and the agent's own computation)."""
        return dict(self._body.seconds)

    # ---------------------------------------------------------- persistence

    def state(self) -> dict:
        """Everything the agent knows, without its body: picklable, for a
        checkpoint between ``start``/``react`` calls. Shares the agent's
        arrays: serialise it before the next call."""
        if self._body.stage is not None:
            raise RuntimeError("state() inside start()/react()")
        attributes = {name: value for name, value in vars(self).items() if name != "_body"}
        sweep = attributes.get("_sweep")
        if sweep is not None:           # its body is the counting body: rebound on restore
            attributes["_sweep"] = {name: value for name, value in vars(sweep).items()
                                    if name != "body"}
        counters = {name: dict(getattr(self._body, name))
                    for name in ("rows", "calls", "seconds", "remembered", "recalled")}
        return {"attributes": attributes, "counters": counters}

    @classmethod
    def from_state(cls, body, state: dict) -> "NaiveAgent":
        """The agent that ``state()`` described, sensing through ``body``;
        it continues exactly as the original would have."""
        attributes = dict(state["attributes"])
        agent = cls(body, attributes["params"])
        sweep = attributes.pop("_sweep", None)
        vars(agent).update(attributes)
        agent._body.phase = agent._phase
        for name, value in state["counters"].items():
            setattr(agent._body, name, dict(value))
        if sweep is not None:
            agent._sweep = EqualitySetSweep.__new__(EqualitySetSweep)
            vars(agent._sweep).update(sweep, body=agent._body)
            agent._sweep.sets = agent._sets
        return agent

    def _measure_body(self, m0: np.ndarray, seed: int) -> np.ndarray:
        """Noise and structure at the start (``noise.measure_body``), the start left for
        one of full measured rank where it is degenerate (``start.choose_start``), the
        tolerances sized from both; returns the start (phases)."""
        given = self.params
        self.structure, self.params = measure_body(self._body, m0, given, self._noise_measured)
        # The step grows above the given one only where noise, not round-off, sized it.
        noisy = self.params.fd_step > given.fd_step
        m0, self.start_choice = choose_start(self._body, m0, self.structure, self.params, seed,
                                             self.structure.noise if noisy else None)
        if self.start_choice is not None and self.start_choice.moved:
            self.structure, self.params = measure_body(self._body, m0, given, self._noise_measured)
        self._fd_step = finite_difference_step(self.params, self.structure,
                                               self._body.n_sensors)
        self.params = averaged_search_params(self.params, self.structure,
                                             self._body.n_sensors, self._fd_step)
        self._repeats = averaging_repeats(self.params, self.structure) if noisy else 1
        self._noisy = bool(noisy)
        self._tol = Tolerances.of(self.params, self.structure,
                                  jacobian_noise(self.structure, self._body.n_sensors,
                                                 self._fd_step),
                                  noise_step(self.params, self.structure, self._fd_step),
                                  noise_residual(self.params, self.structure,
                                                 self._body.n_sensors) if noisy else 0.0)
        return m0

    def start(self, initial_motor_state, seed: int = 0) -> Reaction:
        """Move to ``initial_motor_state`` (or a better start, seeded:
        ``start.choose_start``), sample its POV, record the first anchor."""
        if self._event >= 0:
            raise RuntimeError("start() was already called")
        m0 = np.asarray(initial_motor_state, dtype=float).reshape(-1)
        if m0.shape != (self.n_motors,) or not np.all(np.isfinite(m0)):
            raise ValueError(f"initial_motor_state: must be {self.n_motors} finite numbers, "
                             f"got {initial_motor_state!r}")
        m0 = self._phase.to_phase(m0).copy()
        self._event = 0
        self._body.forget()
        before_rows, before_calls = self._body.total_rows, self._body.total_calls
        self._body.stage = "rank"
        m0 = self._measure_body(m0, seed)
        self._store = PovStore(self.n_samples, self.n_motors)
        new, sensations = self._sample_povs(m0[None])
        self._rest = m0.copy()
        self._rest_pov = new[0] if new else -1
        self._body.stage = "rest"
        rest_sensation = self._rest_sensation(m0)
        current = np.asarray(sensations).reshape(-1, self._body.n_sensors)
        self._pool = [Snapshot(0, current, np.full(len(current), RANK_FULL), rest_sensation,
                                m0.copy(), self._rest_pov,
                                RANK_FULL if new else RANK_UNKNOWN,
                                counts=self._pooled_counts(len(current)),
                                rest_count=self._anchor_repeats())]
        self._body.pause()
        new = np.asarray(new, dtype=int)
        return Reaction(event=0, compensated=False, rest_motor_state=self._to_body(m0),
                        new_pov_ids=new, new_povs=self._to_body(self._store.samples[new]),
                        queries=self._body.total_rows - before_rows,
                        calls=self._body.total_calls - before_calls)

    def react(self, passive_sensation) -> Reaction:
        """Respond to one change of the environment; ``passive_sensation`` is
        the sensation at the resting arm after the change."""
        if self._event < 0:
            raise RuntimeError("react() before start()")
        passive = np.asarray(passive_sensation, dtype=float).reshape(-1)
        # Not used as a value (the sweep senses the resting POV again): a lost
        # frame (non-finite) is accepted.
        if passive.shape != (self._body.n_sensors,):
            raise ValueError(f"passive_sensation: must be {self._body.n_sensors} numbers")
        self._event += 1
        self._body.forget()
        before_rows, before_calls = self._body.total_rows, self._body.total_calls
        if self.phase == EQUALITY_PASS:
            reaction = self._react_equality_pass()
        else:
            reaction = self._react_exploring()
        self._body.pause()
        reaction.queries = self._body.total_rows - before_rows
        reaction.calls = self._body.total_calls - before_calls
        return reaction

    def next_sweep(self) -> np.ndarray | None:
        """The motor states the next ``react`` senses first, ``(K, M)``: one
        sample of every known POV (its sweep), in the environment after the
        next change; None when that call cannot be told now (the equality
        pass sweeps through ``EqualitySetSweep``). A body that can hold a
        command until the next change (the ROS agent's ``BodyOverTopics.
        presend``) answers it with the change, saving a round trip."""
        if self._event < 0 or self.phase != EXPLORING or self._store.count == 0:
            return None
        return self._to_body(self._sweep_rows())

    def begin_equality_pass(self) -> None:
        """Switch to simulation 2: from now on ``react`` only sweeps the known
        POVs and matches each sweep with the previous one (no compensation,
        no new POV), adding one equality set per change. Call it in the
        environment before the first replayed change, then replay them."""
        if self._event < 0:
            raise RuntimeError("begin_equality_pass() before start()")
        self.phase = EQUALITY_PASS
        self._body.forget()
        self._body.stage = "equality_pass"
        self._sweep = self._equality_sweep()
        self._sweep.observe()       # the sweep "before" the first change
        self._body.stage = "rest"
        self._body.rest(self._rest)
        self._body.pause()

    def _equality_sweep(self, kind=EqualitySetSweep) -> EqualitySetSweep:
        """Simulation 2's sweep (a ``kind``) of the known POVs, with the
        agent's measured tolerances, adding to its equality sets."""
        sweep = kind(self._body, self._store.samples, rank=self.structure.pose_rank,
                     fd_step=self._fd_step, rank_ratio=self.params.rank_ratio,
                     min_singular=self._tol.min_singular, pattern_ratio=self.params.pattern_ratio,
                     match_tol=self._tol.match, separation=self._tol.separation)
        sweep.ratio, sweep.sets = self._tol.ratio, self._sets
        return sweep

    # ------------------------------------------------------------ internals

    def _react_equality_pass(self) -> Reaction:
        n_before = self._sets.n_sets
        self._body.stage = "equality_pass"
        self._sweep.observe()
        self._body.stage = "rest"
        self._body.rest(self._rest)
        return Reaction(event=self._event, compensated=False,
                        rest_motor_state=self._to_body(self._rest),
                        new_pov_ids=np.zeros(0, dtype=int),
                        new_povs=np.zeros((0, self.n_samples, self.n_motors)),
                        equality_rows=self._sets.rows_since(n_before))

    def _react_exploring(self) -> Reaction:
        """One change while exploring: sweep and match the snapshots, search
        for their anchors, record the compensations and equality sets, rest,
        and take this event's snapshot."""
        t = self._event
        rows_at_start = self._body.total_rows
        sets_before = self._sets.n_sets
        self._size_repeats()
        # This event's memory of (motor, sensation): the sweep of the known POVs.
        self._body.stage = "sweep"
        current, split_now = self._sweep_known()
        self._split_now = split_now             # what frontier._frontier_order leaves out
        tree = cKDTree(finite_rows(current, -1.0)) if len(current) else None
        matches, rest_hits, rank_now = self._match_snapshots(current, tree)
        matches = self._test_ranks(matches, rest_hits, rank_now, current)
        rest_hits = self._verify_rest_hits(rest_hits)
        matches = self._verify_matches(matches)
        pooled, counts = self._pool_sweep(matches, current)
        known_comp, requests = self._anchor_requests(matches, rest_hits, rank_now, current)

        # Search for the anchors; the new POVs' sensation now is the anchor's.
        pov_rows_before = self._body.rows.get("pov", 0)
        found, new_povs, new_sensations = self._search(requests, current, tree, split_now)
        pov_rows = self._body.rows.get("pov", 0) - pov_rows_before
        if new_povs:
            current = np.vstack([current, np.asarray(new_sensations)])
            if counts is not None:
                pooled = np.vstack([pooled, np.asarray(new_sensations)])
                counts = np.concatenate([counts, np.ones(len(new_povs), dtype=int)])
            rank_now = np.concatenate([rank_now, np.full(len(new_povs), RANK_FULL)])
        found_rest = {r.snapshot: found[i] for i, r in enumerate(requests)
                      if i in found and r.row < 0}
        self._track_frontier(requests, found, new_povs)
        self._add_equality_sets(matches, requests, found)

        records, rest_choice = self._compensation_records(known_comp, found_rest, requests,
                                                          found)
        records = self._hold_unconfirmed(records, matches, known_comp, found_rest)
        self.compensations.extend(records)
        rest_sensation, rest_rank = self._rest_after(rest_choice, rank_now)
        if records:
            self.events_compensated += 1
            self.compensation_queries.append(self._body.total_rows - rows_at_start - pov_rows)
        self._renew_pool(matches, known_comp, found_rest,
                         Snapshot(t, current if counts is None else pooled, rank_now,
                                  rest_sensation, self._rest.copy(), self._rest_pov,
                                  int(rest_rank), counts=counts, rest_count=self._anchor_repeats(),
                                  chained=rest_choice is not None))

        new_idx = np.asarray(new_povs, dtype=int)
        return Reaction(event=t, compensated=bool(records),
                        rest_motor_state=self._to_body(self._rest), new_pov_ids=new_idx,
                        new_povs=self._to_body(self._store.samples[new_idx]),
                        compensations=records, equality_rows=self._sets.rows_since(sets_before))

    def _compensation_records(self, known_comp, found_rest, requests, found):
        """Accepted compensations of this event: the snapshots' anchors (in
        pool order, matched by a known POV or found by search), then the
        frontier rows found. Returns them and the rest choice ``(motor
        state, POV)``: the compensation of the most recent anchor that has
        a POV (tracking it), or None. A POV's first sample is where its
        sensation was recorded: resting there keeps the anchor and the
        sweeps on the very same motor state."""
        t = self._event
        records = []
        rest_choice = None
        for k, snap in enumerate(self._pool):
            if k in known_comp:
                pov, searched = known_comp[k], False
                motor = self._store.samples[pov, 0].copy()
            elif k in found_rest:
                (pov, motor), searched = found_rest[k], True
            else:
                continue
            records.append(CompensationRecord(
                event=t, anchor_event=snap.event,
                anchor_motor_state=self._to_body(snap.rest_motor_state),
                motor_state=self._to_body(motor), pov=int(pov), searched=searched))
            if rest_choice is None and pov >= 0 and (not searched or self._may_rest(k, requests)):
                rest_choice = (motor, int(pov))
        for i, r in enumerate(requests):
            if r.row >= 0 and i in found:
                pov, motor = found[i]
                records.append(CompensationRecord(
                    event=t, anchor_event=self._pool[r.snapshot].event,
                    anchor_motor_state=self._to_body(r.anchor_motor_state),
                    motor_state=self._to_body(motor), pov=int(pov), searched=True))
        return records, rest_choice

    def _rest_after(self, rest_choice, rank_now):
        """Rest at ``rest_choice`` (else stay where the arm is); test the
        rank there if it is not known (filling ``rank_now``). Returns the
        anchor: the sensation at rest and its rank."""
        p = self.params
        if rest_choice is not None:
            self._rest, self._rest_pov = rest_choice[0].copy(), rest_choice[1]
        rest_rank = rank_now[self._rest_pov] if self._rest_pov >= 0 else RANK_UNKNOWN
        if rest_rank == RANK_UNKNOWN:
            self._body.stage = "rank"
            full, _ = check_pose_rank(self._body, self._rest[None],
                                      rank=self.structure.pose_rank, fd_step=self._fd_step,
                                      rank_ratio=p.rank_ratio,
                                      min_singular=self._tol.min_singular,
                                      pattern_ratio=p.pattern_ratio)
            rest_rank = RANK_FULL if full[0] else RANK_DEFICIENT
            if self._rest_pov >= 0:
                rank_now[self._rest_pov] = rest_rank
        self._body.stage = "rest"
        return self._rest_sensation(self._rest), rest_rank

    def _sweep_known(self) -> tuple[np.ndarray, np.ndarray]:
        """Sensation now of every known POV ``(K, S)`` and of every remembered
        split POV ``(Q, S)``, in one call (one sample each: all samples of a
        POV share the eye's pose)."""
        n_sensors = self._body.n_sensors
        if self._store.count == 0:
            return np.zeros((0, n_sensors)), np.zeros((0, n_sensors))
        swept = self._body.sense(self._sweep_rows())
        return swept[:self._store.count], swept[self._store.count:]

    def _sweep_rows(self) -> np.ndarray:
        """The motor states a sweep senses (``_sweep_known``; what ``next_sweep``
        announces must be these rows, bit for bit): the known POVs' first
        samples, then the remembered split POVs' states."""
        rows = self._store.samples[:, 0]
        if len(self._split_states):
            rows = np.concatenate([rows, self._split_states])
        return rows

    def _to_body(self, phases: np.ndarray) -> np.ndarray:
        """A copy of ``phases`` in the body's motor units."""
        return np.array(self._phase.to_body(phases), dtype=float, copy=True)
