"""The naive agent in a world that does not wait for it.

``ClockedAgent`` is a ``NaiveAgent`` that is told nothing about time: its
driver (``core.clocked_run``) calls ``react`` when the agent's own test
(``change_detection``) flags a change. What differs from the agent of a
waiting world:

* a reaction senses a bounded part of what it knows (``clock_sweep``):
  its resting POV and ``sweep_budget`` more, in turn (a cursor walks
  through the known POVs); the others are unknowns this time, as a lost
  frame is. What a reaction costs does not grow with the POVs known. A
  search's solution is compared with the known POVs nearest to it in motor
  space, sensed in this world (``_sense_near``): a solution sensing what one senses is
  that POV, swept or not;
* once its equality sets imply a lattice, a reaction searches the empty
  lattice points its confirmed snapshots point at, not their frontier rows
  (``clock_holes``): the holes in what it knows, not targets known already;
* every call a reaction sends ends with its *sentinels*, the resting state
  of before and a lookout, whose sensations in this world the agent holds
  (``change_detection.Tripwire``; ``sense_sentinels``): when one moved, the world changed
  while the agent was working and the reaction stops (``WorldChanged``);
* a reaction can be undone (``checkpoint``/``restore``): what it found
  spans two worlds and is dropped, its probing still counted, except the
  POVs whose walks were verified before the change, and the search
  solutions whose walk the change cut (``pending``, walked later, one at a
  time: ``walk_pending``). A POV is a set of motor states of one eye pose,
  whatever the world; a walk is valid when all its rows saw one world.
"""
from __future__ import annotations

import pickle
import types

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.seeding import CounterStream
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.clock_equality import AllPairsSweep, translated_sets
from sensorispace_ros.core.naive.clock_holes import HoleTargets
from sensorispace_ros.core.naive.clock_known import KnownNearby
from sensorispace_ros.core.naive.clock_sweep import BoundedSweep
from sensorispace_ros.core.naive.clock_walks import BriefWalks
from sensorispace_ros.core.naive.clock_witnesses import (WITNESSES, Witnesses, brightest,
                                                         senses_nothing)
from sensorispace_ros.core.naive.equality_sets import RANK_UNKNOWN, finite_rows
from sensorispace_ros.core.naive.exploration_yield import ExplorationYield
from sensorispace_ros.core.naive.jacobians import AveragedStep, CloudStep
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.searching import SearchAndSample
from sensorispace_ros.core.naive.change_detection import Tripwire, WorldChanged

__all__ = ["ClockedAgent", "Tripwire", "WITNESSES", "WorldChanged"]

# A reaction only adds to the compensations and the equality sets (their
# records never change): a checkpoint keeps their counts, not copies, and an
# undo cuts them back (simulation 2's sweep adds to the same sets).
COUNTS = "_compensations_and_sets"
STORE = "_store_mark"       # the POV store only grows too: its mark (``PovStore.mark``)


class _CurrentTree:
    """A ``cKDTree`` of the current sensations built when queried: the
    search fills rows of ``current`` (``_sense_near``) after the tree would
    have been built."""

    def __init__(self, current: np.ndarray):
        self._current = current

    def query(self, x, k=1, **kwargs):
        return cKDTree(finite_rows(self._current, -1.0)).query(x, k=k, **kwargs)


class ClockedAgent(KnownNearby, BriefWalks, Witnesses, BoundedSweep, HoleTargets, NaiveAgent):
    """``NaiveAgent`` with a bounded sweep and undoable reactions (module docstring)."""

    # A row remembered from before a change the sentinels have not flagged yet
    # would join rows of the new world in one call: only whole calls are recalled.
    _partial_recall = False

    def _note_verified(self, *verified) -> None:
        """On a clock the POVs stay as found: nothing is kept to move them
        (``naive.relax_povs`` applies where the world waits)."""

    def __init__(self, body, params: NaiveParams | None = None, sweep_budget: int = 64):
        self._tripwire = Tripwire(body)
        super().__init__(self._tripwire, params)
        self._tripwire.every = self.params.clock_sentinel_rows \
            if self.params.clock_walk_attempts == 1 else 0      # a crossing needs every call's
        if isinstance(sweep_budget, bool) or not isinstance(sweep_budget, (int, np.integer)) \
                or sweep_budget < 0:
            raise ValueError(f"sweep_budget: must be an integer >= 0, got {sweep_budget!r}")
        self.sweep_budget = int(sweep_budget)
        self._sweep_cursor = 0
        self.pending = np.zeros((0, self.n_motors))   # solutions whose walk a change cut
        self._verified = 0          # POVs stored whose every row passed a sentinel
        self._cut_walk = None       # the start states of a walk a change cut
        self._search_current = None
        self._witnesses = None      # (states, sensations) of this reaction's sweep
        self._lookouts = None       # states (phases) a reaction's lookout is chosen from
        self._lookout = None        # (state, sensation) the next reaction watches
        self.cut_stage = None       # the stage a sentinel stopped last
        self.crossing = None        # a walk's change in this reaction (``_cross``)
        self.crossings = 0          # walks started again in a new world
        self._search_end = 0        # the tripwire's rows sent when the walks began
        self._yield = ExplorationYield(self.params.clock_stop_ratio, self.params.clock_stop_window)

    # ------------------------------------------------------------ the clock

    @property
    def noise_sd(self) -> float:
        """The per-receptor noise the agent measured (0 before ``start``)."""
        return 0.0 if self.structure is None else float(self.structure.noise)

    def explored(self) -> bool:
        """Whether exploring has stopped paying (``ExplorationYield``), from
        the motor states probed and the POVs known now."""
        return self._yield.explored(self.queries_total, self._store.count)

    @property
    def explored_at(self) -> int:
        """The motor states probed when exploring stopped paying (0: it never
        did; an agent saved before the rule existed has none)."""
        rule = getattr(self, "_yield", None)
        return 0 if rule is None or rule.stopped_at is None else int(rule.stopped_at)

    @property
    def anchor_sensation(self) -> np.ndarray | None:
        """The sensation recorded at the resting state in its last reaction
        (``_rest_after``; before any, the start's snapshot's). Not the newest
        snapshot's: with ``chained_anchors`` a reaction whose rest is not
        chained to the start's takes none."""
        sensed = getattr(self, "_rest_sensed", None)
        if sensed is None:
            return None if not self._pool else self._pool[0].rest_sensation.copy()
        return sensed.copy()

    @property
    def queries_total(self) -> int:
        return self._body.total_rows + self._tripwire.rows

    @property
    def queries_by_stage(self) -> dict:
        """Rows per stage; the sentinels count as resting rows."""
        rows = dict(self._body.rows)
        rows["rest"] = rows.get("rest", 0) + self._tripwire.rows
        return rows

    def sense_again(self, motor_states) -> np.ndarray:
        """Sense ``motor_states`` (body units) afresh, not from memory:
        counted as resting rows."""
        rows = self._phase.to_phase(np.atleast_2d(np.asarray(motor_states, dtype=float)))
        self._body.stage = "rest"
        with self._body.fresh():
            sensed = self._body.sense(np.ascontiguousarray(rows))
        self._body.pause()
        return sensed

    def watched(self, reaction, sensed_at_rest):
        """``reaction(sensed_at_rest)`` (``react``) or ``reaction()``
        (``begin_equality_pass``) with the sentinel armed: the resting state
        at the call, whose sensation in this world is ``sensed_at_rest``. Raises
        ``WorldChanged`` (the agent then inside an unfinished reaction:
        ``restore`` it)."""
        states, held = [self.rest_motor_state], [sensed_at_rest]
        if self._lookout is not None:
            states.append(self._lookout[0])
            held.append(self._lookout[1])
            self._lookout = None
        self._tripwire.arm(np.vstack(states), np.vstack(held), self.noise_sd)
        self._verified = self._store.count
        self._cut_walk = None
        self._witnesses = None
        self.crossing = None
        try:
            done = reaction(sensed_at_rest) if reaction == self.react else reaction()
            self._tripwire.flush()
            return done
        except WorldChanged:
            self.cut_stage = self._body.stage or "rest"     # its last sentinels
            raise
        finally:
            self._tripwire.disarm()
            self._body.pause()

    def sense_sentinels(self, rest) -> np.ndarray:
        """Sense the resting state ``rest`` (body units) afresh, with the
        lookout candidates (the last sweep's witnesses, else the first known
        POVs) after it in the same call; the candidate that sensed most, if it
        senses something, becomes the lookout the next reaction watches beside
        its resting state (``change_detection.Tripwire``): a resting state that
        senses nothing sees no change. Where both sense nothing, known POVs in
        turn (``_lookout_among_known``). Returns the resting state's sensation."""
        candidates = self._lookouts if self._lookouts is not None else \
            self._store.samples[:WITNESSES, 0]
        candidates = self._to_body(candidates).reshape(-1, self.n_motors)
        sensed = self.sense_again(np.vstack([np.asarray(rest, float)[None], candidates]))
        self._lookout = brightest(candidates, sensed[1:], self.noise_sd)
        if self._lookout is None and senses_nothing(self.noise_sd, sensed[0]):
            self._lookout = self._lookout_among_known()
        return sensed[0]

    def walk_pending(self, sensed_at_rest) -> int:
        """Walk the oldest pending solution, watched as a reaction is; the
        sentinel is sensed once more after the walk. Returns the POVs added
        (0 or 1). Raises ``WorldChanged`` (``restore`` the agent then)."""
        if not len(self.pending):
            return 0
        state, self.pending = self.pending[0], self.pending[1:]
        self._tripwire.arm(self.rest_motor_state, sensed_at_rest, self.noise_sd)
        self.crossing = None
        if self.params.clock_walk_attempts > 1:
            self._body.forget()
        try:
            if self._pending_known(state):
                return 0
            new, _ = self._walk_through(state[None])
            self._tripwire.check()
        finally:
            self._tripwire.disarm()
            self._body.pause()
        return len(new)

    def start(self, initial_motor_state, seed: int = 0):
        """``NaiveAgent.start``, its rows after the noise call watched by the
        start state (``_noise_measured``): a change cuts it (``WorldChanged``)."""
        self._seed = int(seed)
        try:
            return super().start(initial_motor_state, seed=seed)
        finally:
            self._tripwire.disarm()

    def _noise_measured(self, center: np.ndarray, noise) -> None:
        """Once the start measured its noise at ``center`` (phases): that state
        is the sentinel of every later call of the start, held to what its
        repeats in the noise call sensed. A start is made in one world; a
        change stops it at the next call rather than after all its rows."""
        self._tripwire.arm(self._phase.to_body(center[None]), noise.center[None], noise.sd)

    def _equality_sweep(self, kind=AllPairsSweep):
        """Simulation 2 with every earlier sweep matched (``AllPairsSweep``),
        each sweep ``clock_equality_budget`` known POVs (0: every one)."""
        sweep = super()._equality_sweep(kind)
        sweep.history = []
        sweep.budget = self.params.clock_equality_budget
        sweep.stream = CounterStream(getattr(self, "_seed", 0), "naive.clock_equality")
        return sweep

    def _found_sets(self):
        """The sets of changes, then the sets of segments they imply
        (``clock_equality.translated_sets``, ``clock_translated_pairs`` changes a set)."""
        pairs, set_ids = super()._found_sets()
        per_set = self.params.clock_translated_pairs
        if per_set < 2 or not len(pairs):
            return pairs, set_ids
        more, more_ids = translated_sets(pairs, set_ids, self._store.count, per_set,
                                         stream=CounterStream(getattr(self, "_seed", 0),
                                                              "naive.clock_translated"))
        return np.concatenate([pairs, more]), np.concatenate([set_ids, more_ids + self._sets.n_sets])

    def checkpoint(self) -> dict:
        """What the agent knows (its counters excluded), to undo a reaction;
        of its compensations, equality sets and POVs, their counts (``COUNTS``, ``STORE``)."""
        kept = {name: value for name, value in vars(self).items()
                if name not in ("_body", "_tripwire", "_sets", "compensations", "_store")
                and not isinstance(value, (types.FunctionType, types.MethodType))}
        if self._sweep is not None:     # simulation 2's sweep senses through the body
            kept["_sweep"] = {name: value for name, value in vars(self._sweep).items()
                              if name not in ("body", "sets")}
        # A pickle's round trip copies as deepcopy does, several times faster.
        saved = pickle.loads(pickle.dumps(kept, protocol=pickle.HIGHEST_PROTOCOL))
        saved[COUNTS] = (len(self.compensations), self._sets.n_sets)
        saved[STORE] = self._store.mark()
        return saved

    def restore(self, saved: dict, salvage: bool = True) -> int:
        """Back to ``saved``; the rows spent since stay counted. With
        ``salvage``, the POVs verified since are kept and the solutions of a
        cut walk are pending (module docstring). Returns the POVs kept."""
        first, first_q = saved[STORE][0], len(saved["pov_queries"])
        kept = max(0, self._verified - first) if salvage else 0
        samples = self._store.samples[first:first + kept].copy()
        queries = list(self.pov_queries[first_q:first_q + kept])
        cut = self._cut_walk if salvage else None
        restored = pickle.loads(pickle.dumps(saved, protocol=pickle.HIGHEST_PROTOCOL))
        sweep = restored.pop("_sweep", None)
        n_compensations, n_sets = restored.pop(COUNTS)
        self._store.truncate(restored.pop(STORE))
        self._sets.truncate(n_sets)
        self.compensations = self.compensations[:n_compensations]
        vars(self).update(restored)
        self._body.phase = self._phase
        if sweep is not None:
            self._sweep = AllPairsSweep.__new__(AllPairsSweep)
            vars(self._sweep).update(sweep, body=self._body, sets=self._sets)
        else:
            self._sweep = None
        for pov, walked in zip(samples, queries):
            self._store.append(pov)
            self.pov_queries.append(int(walked))
            self.pov_events.append(self._event)
        if cut is not None:
            # Every call of the search before the walk passed its sentinel.
            self.pending = np.vstack([self.pending, cut])
        return kept

    def _anchor_requests(self, matches, rest_hits, rank_now, current=None):
        self._lost = not (np.any(np.asarray(rest_hits) >= 0) or
                          any(len(before) for before, _ in matches))
        known_comp, requests = super()._anchor_requests(matches, rest_hits, rank_now, current)
        if current is not None:     # this reaction's requests (not the rank tests' guess)
            requests = self._hole_requests(matches, requests)
            self._unconfirmed_asked = [
                i for i, r in enumerate(requests) if r.row < 0 and not len(matches[r.snapshot][0])
                and self._store.count >= self.params.unconfirmed_max_povs]
            self._spend_unconfirmed(len(self._unconfirmed_asked))
        return known_comp, requests

    def _spend_unconfirmed(self, asked: int) -> None:
        """A reaction asked ``asked`` unconfirmed anchors: each costs one
        credit, and each reaction earns ``_unconfirmed_rate`` (one at most
        held); the next searches one only with a whole credit."""
        credit = getattr(self, "_unconfirmed_credit", 1.0) - asked
        self._unconfirmed_credit = min(1.0, credit + self._unconfirmed_rate())

    def _unconfirmed_found(self, found: bool) -> None:
        """The moving average of the unconfirmed anchors' searches that succeeded."""
        self._unconfirmed_success = 0.9 * getattr(self, "_unconfirmed_success", 1.0) + \
            0.1 * bool(found)

    def _unconfirmed_rate(self) -> float:
        """Share of reactions that search an unconfirmed anchor once more than
        ``unconfirmed_max_povs`` POVs are known: all while such searches find
        compensations (a moving average, as the frontier's), down to
        ``clock_unconfirmed_min_rate`` when they keep failing."""
        share = min(1.0, getattr(self, "_unconfirmed_success", 1.0) / 0.2)
        return max(self.params.clock_unconfirmed_min_rate, share)

    def _frontier_holes(self):
        """None: on a clock its own hole targets replace the frontier rows
        (``clock_holes``); until they do, the rows keep their order."""
        return None

    def _anchor_params(self):
        """The agent's parameters, except that once it knows more POVs than
        ``unconfirmed_max_povs`` it still searches for one unconfirmed anchor
        in a share of its reactions (``_unconfirmed_rate``; each while they find
        compensations): with a bounded sweep most snapshots go unconfirmed (their
        matches were not sensed), not only those a redistribution made stale.
        With ``clock_unconfirmed_when_lost`` only in a reaction whose sweep
        confirmed no snapshot (``_lost``): one that did has its compensation
        to search, and an unconfirmed anchor is seldom found."""
        params = self.params
        if self._store.count >= params.unconfirmed_max_povs:
            attempts = min(params.unconfirmed_attempts, 1)
            if params.clock_unconfirmed_when_lost and not getattr(self, "_lost", True):
                attempts = 0
            if getattr(self, "_unconfirmed_credit", 1.0) < 1.0:
                attempts = 0
            params = params.with_counts(unconfirmed_max_povs=self._store.count + 1,
                                        unconfirmed_attempts=attempts)
        return params

    def _search(self, requests, current, tree, split_now):
        asked = self._unswept_targets(requests, current) if tree is not None else range(
            len(requests))
        self._search_current = current
        try:
            found, new_povs, sensations = super()._search(
                [requests[i] for i in asked], current,
                None if tree is None else _CurrentTree(current), split_now)
        finally:
            self._search_current = None
        found = {asked[i]: value for i, value in found.items()}
        self._track_holes(found, new_povs)
        for i in getattr(self, "_unconfirmed_asked", ()):
            self._unconfirmed_found(i in found)
        self._unconfirmed_asked = []
        return found, new_povs, sensations

    def _search_options(self) -> dict:
        """A target's starts searched in turn (``clock_search_in_turn``), ``clock_search_turns``
        of them at most, each trial state sensed alone first (``clock_search_probe_first``)
        where noise sized none of the tolerances (under noise measured on one run only:
        docs/clock.md): fewer rows, fewer cut."""
        return {"in_turn": bool(self.params.clock_search_in_turn),
                "max_turns": int(self.params.clock_search_turns),
                "probe_first": bool(self.params.clock_search_probe_first) and not self._noisy}

    def _search_lookahead(self, starts: np.ndarray) -> np.ndarray:
        """Searching in turn, a search senses its starts first, and a start's
        stencil only when its turn comes (``compensation.compensate``): the
        starts not remembered since the change."""
        if not self.params.clock_search_in_turn or \
                isinstance(self._first_search_step(), (AveragedStep, CloudStep)):
            return super()._search_lookahead(starts)
        starts = np.asarray(starts, dtype=float).reshape(-1, self.n_motors)
        return starts[[self._body._recall(row[None]) is None for row in starts]]

    def _run_searches(self, unique_targets, owner, starts):
        solution, others, gain = super()._run_searches(unique_targets, owner, starts)
        if self._search_current is not None and solution:
            self._sense_near(self._search_current, np.stack(list(solution.values())))
        return solution, others, gain

    def _sample_povs(self, motor_states, keep_invalid=False, others=None):
        if self._tripwire.armed and self.params.clock_walk_attempts > 1 and \
                self.witnesses_moved():
            # A change the sentinel does not see cut the search: a walk must
            # not carry it into a reaction kept across a change (``_cross``).
            self.cut_stage = "compensation"
            raise WorldChanged(None)
        self._tripwire.flush()
        self._search_end = self._tripwire.sent
        try:
            walked = self._walk_through(motor_states, keep_invalid=keep_invalid, others=others)
            self._tripwire.flush()
        except WorldChanged:
            if self._tripwire.armed:
                self._cut_walk = np.array(motor_states, dtype=float)
            raise
        # Every call of the walk passed its sentinel, and so did the search's before it.
        self._verified = self._store.count
        return walked

    def _walk_through(self, motor_states, keep_invalid=False, others=None):
        """``SearchAndSample._sample_povs``, started again in the new world
        when a change cuts it (``params.clock_walk_attempts`` worlds at most): the states
        of one eye pose sense alike in any world, so the level set through a
        solution is its POV whichever world it is walked in. A walk is kept
        when every one of its rows saw one world."""
        attempts = self.params.clock_walk_attempts
        for attempt in range(attempts):
            try:
                return SearchAndSample._sample_povs(self, motor_states, keep_invalid=keep_invalid,
                                                    others=others)
            except WorldChanged as stop:
                if not self._tripwire.armed or attempt == attempts - 1:
                    raise
                self._cross(np.asarray(stop.args[-1], dtype=float))
        raise AssertionError("unreachable")

    def _cross(self, sensed: np.ndarray) -> None:
        """The sentinel's sensation left its band in a walk: the world changed.
        The rows before the last sentinel that passed (the search's) saw the
        world of before; the walk starts again in the new one, the sentinel
        held to ``sensed``, what was sensed before forgotten. ``crossing``
        notes the first such change of the reaction (``passed``: the
        tripwire's rows sent when the walks began, after the witnesses of the
        search passed, ``fired``:
        up to the one that flagged), the latest reference and the rows sent
        up to it (``latest``)."""
        tripwire = self._tripwire
        if self.crossing is None:
            self.crossing = {"passed": self._search_end, "fired": tripwire.sent}
        sensed = sensed.reshape(-1, tripwire.n_sensors)
        self.crossing.update(reference=sensed[0].copy(), latest=tripwire.sent)
        self.crossings += 1
        tripwire.rearm(sensed)
        self._body.forget()

    rows_sent = property(lambda self: self._tripwire.sent, doc="Rows sent, sentinels included.")

    def _rest_after(self, rest_choice, rank_now):
        """``NaiveAgent._rest_after``; after a walk crossed a change the arm
        stays where it rests and takes no snapshot (its sweep saw the world
        of before, its rest would sense the new one)."""
        if self.crossing is not None:
            return None, RANK_UNKNOWN
        sensation, rank = super()._rest_after(rest_choice, rank_now)
        self._rest_sensed = sensation
        return sensation, rank

    def _renew_pool(self, matches, known_comp, found_rest, snapshot) -> None:  # not after a crossing
        if self.crossing is None:
            super()._renew_pool(matches, known_comp, found_rest, snapshot)
