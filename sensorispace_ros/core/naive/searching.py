"""The naive agent's searches and POV sampling (``NaiveAgent`` inherits them).

``_search`` runs the batched Levenberg-Marquardt searches toward this
event's anchors and samples the POVs of the new solutions; ``_sample_povs``
walks (or covers) POVs of the dimension the agent measured and stores the
whole ones. For 0-D POVs the searches toward one target keep going after the
first acceptance, and every distinct solution they find belongs to that
target's POV. Tolerances on sensations are the agent's ``Tolerances``.
Where noise sized them, a search's end is refined and passes ``confirm``
(chi-square tests of its averaged residual, its predicted pose error held
to ``pose_precision`` of the separation of the POVs found), anchors are
averaged (``_rest_sensation``), and a walked POV is kept only if all its
samples sense its start's sensation (``_whole_on_level_set``).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2

from sensorispace_ros.core.motor_loops import doubles_back, wrap_phase
from sensorispace_ros.core.naive.compensation import compensate
from sensorispace_ros.core.naive.confirm import confirm_compensations, finite_mean
from sensorispace_ros.core.naive.equality_sets import finite_rows
from sensorispace_ros.core.naive.jacobians import SPLIT, AveragedStep, SymmetricStep, stencil_rows
from sensorispace_ros.core.naive.known_loops import KnownLoops
from sensorispace_ros.core.naive.noise import (jacobian_noise, noise_residual, noise_step,
    walk_step)
from sensorispace_ros.core.naive.points_of_view import (isolated_samples,
    sample_sensory_points_of_view)

# Times the expected spectral norm of the receptors' noise in a confirmed
# state's Jacobian that its weakest pose direction must clear: the norm of
# pure noise rarely exceeds its expectation by half, and twice it also
# refuses most of what the secant bends along a direction the sensation
# does not follow.
_RECEPTOR_GAP = 2.0


class SearchAndSample(KnownLoops):
    """Mixin of ``NaiveAgent``: needs its ``params``, ``structure``, ``_tol``,
    ``_body``, ``_store``, ``_rest``, ``_split_states`` and counters."""

    def _search(self, requests, current, tree, split_now):
        """LM toward every requested anchor (identical targets searched once)
        from the request's own start, the resting state and the remembered
        states that sense most like the target; sample the POVs of accepted
        solutions that are not known POVs. ``split_now``: sensations of the
        remembered split POVs in this environment; a solution sensing one of
        them is on that loop, already walked and found split: not walked
        again (its POV is -1, as after a split walk).

        Returns ``{request index: (pov or -1, motor state)}`` for accepted
        compensations, the new POV indices and their sensations.
        """
        if not requests:
            return {}, [], []
        group, unique_targets, owner, starts = self._search_plan(requests, current)
        solution, others, gain = self._run_searches(unique_targets, owner, starts)
        if self._noisy and solution:
            # Sensings averaged in each target: anchors at rest ``_repeats``, a
            # sweep's row as many as its chain of matches pooled (``Request.count``).
            counts = {g: requests[int(np.flatnonzero(group == g)[0])].count for g in solution}
            solution = self._confirm_searched(solution, unique_targets, counts, requests, group)
            solution = self._held_by_neighbours(solution, requests, group)
        pov_of_group, fresh = self._known_solutions(solution, unique_targets, gain, tree,
                                                    split_now)
        new_povs, new_sensations = [], []
        known_before = self._store.count
        if fresh:
            povs, sensations = self._sample_povs(np.stack([solution[g] for g in fresh]),
                                                 keep_invalid=True,
                                                 others=[others[g] for g in fresh])
            for g, pov, sensation in zip(fresh, povs, sensations):
                pov_of_group[g] = pov
                if pov >= known_before and pov not in new_povs:
                    new_povs.append(pov)
                    new_sensations.append(sensation)
        found = {i: (pov_of_group[group[i]], solution[group[i]])
                 for i in range(len(requests)) if group[i] in solution}
        return found, new_povs, new_sensations

    def _known_solutions(self, solution, unique_targets, gain, tree, split_now):
        """Which solutions ``{group: state}`` are known POVs (``tree``: their
        sensations in this environment) or remembered split ones (``split_now``). Returns
        ``({group: known POV or -1}, [groups to walk])``."""
        pov_of_group: dict[int, int] = {}
        # A solution sensing what a known POV senses now is that POV (the
        # solution has full rank, so the sensation pins the pose). "The same"
        # is judged by the sensory gain at the solution: a motor-equivalent
        # distance of match_tol; where the Jacobians are averaged (the match
        # tolerance, which allows for drift along chains, then spans
        # neighbouring poses) within what two sensings of one pose differ by;
        # under noise only a solution on that POV's loop, and also a solution
        # on a known POV's loop; one between loops is refused (``known_loops``).
        fresh = []
        split_tree = cKDTree(finite_rows(split_now, -1.0)) if len(split_now) else None
        for g in sorted(solution):
            same = self.params.match_tol * gain[g]
            if isinstance(self._fd_step, AveragedStep) and self._tol.ratio > 0:
                same = min(same, self._tol.separation)
            if tree is not None:
                distance, index = tree.query(unique_targets[g], k=1)
                if distance <= same and self._on_known_loop(solution[g], int(index)):
                    pov_of_group[g] = int(index)
                    continue
            known, refused = self._placed_end(solution[g])
            if known >= 0 or refused:
                pov_of_group[g] = known
                self.ends_between_loops += int(refused)
                continue
            if split_tree is not None and split_tree.query(unique_targets[g], k=1)[0] <= same:
                pov_of_group[g] = -1
                self.split_walks_skipped += 1
                continue
            fresh.append(g)
        return pov_of_group, fresh

    def _rest_sensation(self, motor_state: np.ndarray) -> np.ndarray:
        """Rest at ``motor_state``; its sensation, the anchor: averaged over
        ``_anchor_repeats()`` sensings (lost ones left out) where noise sized
        the tolerances, so a compensation toward it is judged against the
        noise of the search's end alone (``confirm.confirm_compensations``)."""
        repeats = self._anchor_repeats()
        if repeats <= 1:
            return self._body.rest(motor_state)
        with self._body.fresh():
            more = self._body.sense(np.repeat(motor_state[None], repeats - 1, axis=0))
            sensation = self._body.rest(motor_state)
        return finite_mean(np.vstack([sensation[None], more]))

    def _anchor_repeats(self) -> int:
        """Sensings averaged in the anchor recorded at rest: ``_repeats``; where
        random noise sized the tolerances and fewer than
        ``unconfirmed_max_povs`` POVs are known (its anchor may be searched
        with no match to confirm its snapshot, ``anchors.anchor_requests``),
        ``accept_max_repeats``: across a redistribution no match reveals,
        only the sensation tells a far pose sensing the anchor alike, and
        a sensing's noise hides what sets them apart."""
        if self._repeats > 1 and self._noisy and \
                self._store.count < self.params.unconfirmed_max_povs:
            return max(self._repeats, int(self.params.accept_max_repeats))
        return self._repeats

    def _confirm_searched(self, solution, unique_targets, counts, requests, group):
        """``_confirm`` of the searches' ``solution`` ``{group: state}``; the
        ends of compensations of an anchor no match confirmed (no neighbours
        hold them, ``anchors._held_by_neighbours``) averaged as often as
        their targets were (``_anchor_repeats``), so that what sets a far
        pose apart is not hidden by the end's noise."""
        lone = {g for g in solution if any(r.row < 0 and r.neighbours is None
                                           for r, h in zip(requests, group) if h == g)}
        kept = {}
        rest = {g: state for g, state in solution.items() if g not in lone}
        if rest:
            kept.update(self._confirm(rest, unique_targets, counts))
        if lone:
            repeats = max(self._repeats, max(counts[g] for g in lone))
            kept.update(self._confirm({g: solution[g] for g in lone}, unique_targets, counts,
                                      repeats=repeats))
        return kept

    def _confirm(self, solution, unique_targets, counts, rounds=None, max_step=None,
                 repeats=None):
        """The searches' solutions that pass ``confirm.confirm_compensations``
        (refined with averaged residuals); ``counts[g]``: the sensings
        averaged in group ``g``'s target; ``rounds`` (default
        ``confirm_rounds``) of refinement; ``max_step`` as
        ``confirm_compensations``'s; ``repeats`` (default ``_repeats``) the
        sensings averaged per round."""
        groups = sorted(solution)
        sd2 = self.structure.noise ** 2
        if max_step is None and self._repeats <= 1 and self.structure.quantum <= 0:
            # Float rounding repeats exactly and lies on no lattice: sensing the
            # end again cannot refine it; one step with the residual, accepted
            # where the noise explains it. Outputs rounded to a lattice round
            # anew at each refined state: the rounds go on until the residual in
            # range is the rounding's (one difference's Jacobian may hide the
            # weakest direction, and one step along it may land far off).
            max_step = np.inf
        self._body.stage = "compensation"
        stepped, accepted, _ = confirm_compensations(
            self._body, np.stack([solution[g] for g in groups]), unique_targets[groups],
            np.array([sd2 / counts[g] for g in groups]),
            noise_sd=self.structure.noise, repeats=repeats or self._repeats,
            rank=self.structure.pose_rank, fd_step=self._fd_step,
            confidence=self.params.noise_confidence,
            rounds=self.params.confirm_rounds if rounds is None else rounds,
            max_error=self._max_pose_error(), max_step=max_step,
            min_singular=self._pinning_floor())
        return {g: stepped[i] for i, g in enumerate(groups) if accepted[i]}

    def _pinning_floor(self) -> float:
        """The ``rank``-th singular value a confirmed state's averaged
        Jacobian must exceed where random noise was measured (0 where the
        repeats do not spread): the expected spectral norm of its noise
        (``noise.jacobian_noise``), and ``_RECEPTOR_GAP`` times that of the
        receptors' part (``BodyStructure.receptor_noise``). Receptor noise
        errs in every direction and can fake one the sensation does not
        follow; a joint's error moves the sensation along the Jacobian's
        range, so it lifts the first term, not the second. A bend the
        secant sees above the floor is refused at half the step
        (``confirm._slope_holds``)."""
        if self._repeats <= 1:
            return 0.0
        norm = jacobian_noise(self.structure, self._body.n_sensors, self._fd_step)
        receptors = self.structure.receptor_noise / self.structure.noise
        return norm * max(1.0, _RECEPTOR_GAP * receptors)

    def _size_repeats(self) -> None:
        """With an ``AveragedStep``, once the POVs' separation is measured:
        the sensings averaged per anchor and per round of a search's end
        (``_repeats``) as many as keep the predicted pose error of a
        compensation between two such averages within ``_max_pose_error``
        where the weakest singular value is half the one measured at the
        start, ``accept_repeats`` to ``accept_max_repeats``. Elsewhere
        unchanged."""
        limit = self._max_pose_error()
        if not isinstance(self._fd_step, AveragedStep) or not np.isfinite(limit) or \
                self.structure.weakest <= 0:
            return
        # Two averages of R sensings: variance 2 sd^2 / R, over (weakest / 2)^2.
        wanted = 8.0 * (self.structure.noise / (limit * self.structure.weakest)) ** 2
        self._repeats = int(np.clip(np.ceil(wanted), self.params.accept_repeats,
                                    self.params.accept_max_repeats))

    def _max_pose_error(self) -> float:
        """The largest predicted pose error (motor space, one standard
        deviation) a compensation may keep: ``pose_precision`` times the
        separation of the distinct POVs found so far (``PovStore.separation``;
        none while fewer than ``pose_precision_povs`` are known)."""
        if self._store.count < self.params.pose_precision_povs:
            return np.inf
        return self.params.pose_precision * self._store.separation()

    def _run_searches(self, unique_targets, owner, starts):
        """The batched searches. Returns ``{group: best accepted state}``,
        ``{group: other distinct accepted states (K, M)}`` (empty unless the
        POVs are 0-D, where each is another solution of the same sensation)
        and ``{group: sensory gain at the best state}``."""
        p = self.params
        isolated = self.structure.pov_dim == 0
        self._body.stage = "compensation"
        search = self._compensate(unique_targets[owner], starts, isolated)
        solution: dict[int, np.ndarray] = {}
        others: dict[int, np.ndarray] = {}
        gain: dict[int, float] = {}
        for g in range(len(unique_targets)):
            ok = np.flatnonzero((owner == g) & search.accepted)
            if not len(ok):
                continue
            ok = ok[np.argsort(search.sensory_error[ok], kind="stable")]
            solution[g] = search.motor_states[ok[0]]
            gain[g] = float(search.gain[ok[0]])
            others[g] = _distinct(search.motor_states[ok], p.pov_min_step)[1:] if isolated \
                else np.zeros((0, self.n_motors))
        return solution, others, gain

    def _compensate(self, targets, starts, isolated):
        """``compensation.compensate`` with the agent's parameters. With an
        ``AveragedStep`` in two passes: every search with one sensing per
        stencil row (a ``SymmetricStep`` of the same size, held to what one
        sensing's noise allows: most searches never come near their target
        and stop on that), then the accepted ones again from where they
        ended with the averaged stencil and tolerances."""
        p = self.params
        common = dict(rank=self.structure.pose_rank, min_singular=self._tol.min_singular,
                      pattern_ratio=p.pattern_ratio, max_iterations=p.lm_max_iterations,
                      motor_tol=p.lm_motor_tol, rank_ratio=p.rank_ratio, max_step=p.lm_max_step,
                      initial_damping=p.lm_initial_damping,
                      stall_iterations=p.lm_stall_iterations, stop_found_targets=not isolated,
                      **self._search_options())
        fine = dict(fd_step=self._fd_step, error_tol=p.lm_error_tol,
                    noise_step=self._tol.noise_step)
        if not isinstance(self._fd_step, AveragedStep):
            return compensate(self._body, targets, starts, **common, **fine)
        coarse = compensate(self._body, targets, starts, **common,
                            fd_step=self._first_search_step(),
                            error_tol=self._coarse_error_tol(),
                            noise_step=noise_step(p, self.structure))
        found = np.flatnonzero(coarse.accepted)
        coarse.accepted[:] = False
        if len(found):
            refined = compensate(self._body, targets[found], coarse.motor_states[found],
                                 **common, **fine)
            for name in ("motor_states", "sensory_error", "gain", "motor_residual",
                         "rank_ratio", "accepted"):
                getattr(coarse, name)[found] = getattr(refined, name)
            coarse.queries[found] += refined.queries
            coarse.calls += refined.calls
        return coarse

    def _search_options(self) -> dict:
        """More arguments of every ``compensate`` call (none here)."""
        return {}

    def _first_search_step(self):
        """The step of a search's first pass (``_compensate``): one sensing per
        stencil row where the agent averages them, else its step."""
        if isinstance(self._fd_step, AveragedStep):
            return SymmetricStep(float(self._fd_step))
        return self._fd_step

    def _coarse_error_tol(self) -> float:
        """The sensory error (motor-equivalent) a first pass accepts: twice the
        ``noise_confidence`` quantile of what two single sensings of one pose
        differ by, over the gain."""
        n_sensors = self._body.n_sensors
        return 2.0 * noise_residual(self.params, self.structure, n_sensors) / \
            self.structure.gain

    def _search_plan(self, requests, current):
        """The searches for ``requests`` (not empty): identical targets are
        searched once, from the request's own start, the resting state and the
        known POVs that sense most like the target now. Returns ``(group of
        each request, unique targets (G, S), owner group of each search (K,),
        starts (K, M))``."""
        p = self.params
        targets = np.stack([r.target for r in requests])
        # Under noise the match tolerance allows for drift along chains; two
        # targets are one only within what two sensings of one pose differ by.
        same = self._tol.match if self._tol.ratio == 0 else min(self._tol.match,
                                                                self._tol.separation)
        group = _group_rows(targets, same)
        n_groups = int(group.max()) + 1
        first = [int(np.flatnonzero(group == g)[0]) for g in range(n_groups)]
        unique_targets = targets[first]
        starts, owner = [], []
        for g, target in enumerate(unique_targets):
            # The agent's memory of this arrangement is the known POVs it just
            # sensed: start from those that sense most like the target.
            chosen = [self._rest]
            if requests[first[g]].start is not None:
                chosen.append(requests[first[g]].start)
            if len(current):
                nearest = np.argsort(np.linalg.norm(current - target, axis=1))[:p.lm_restarts]
                chosen.extend(self._store.samples[nearest, 0])
            if p.probe_grid:
                chosen.extend(self._probe_starts(target))
            starts.extend(chosen)
            owner.extend([g] * len(chosen))
        return group, unique_targets, np.asarray(owner), np.asarray(starts, dtype=float)

    def _whole_on_level_set(self, walk) -> np.ndarray:
        """Where noise sized the tolerances: which walked POVs have every
        sample sensing their start's sensation within ``SLID`` times what
        two sensings differ by (one call, every sample of every valid walk); a walk
        that slid along a weak pose direction, or onto another pose with a
        like sensation, is not one POV. Nor is one whose loop doubles back
        (``motor_loops.doubles_back``): a front that turned round, where
        noise hid which way the level set went on. True everywhere else."""
        whole = np.ones(len(walk.valid), dtype=bool)
        valid = np.flatnonzero(walk.valid)
        if not self._noisy or not len(valid):
            return whole
        samples = walk.samples[valid]
        sensed = self._body.sense(samples.reshape(-1, samples.shape[2]))
        residual = sensed.reshape(len(valid), samples.shape[1], -1) - \
            walk.target_sensations[valid][:, None, :]
        with np.errstate(invalid="ignore"):
            worst = np.max(np.sum(residual ** 2, axis=2), axis=1)
        limit = self._level_set_allowance(walk, samples.shape[1], residual.shape[2])
        whole[valid] = ~(worst > limit) & ~doubles_back(samples)  # a lost row rejects no POV
        return whole

    def _level_set_allowance(self, walk, n_samples: int, n_sensors: int) -> float:
        """The squared distance from its start's sensation no sample of a whole
        POV exceeds: ``SLID`` times what two sensings differ by, at the
        ``noise_confidence`` chi-square quantile (``S`` degrees of freedom)
        shared among its ``n_samples`` samples."""
        quantile = chi2.ppf(1.0 - (1.0 - self.params.noise_confidence) / n_samples, n_sensors)
        return SLID ** 2 * 2.0 * self.structure.noise ** 2 * float(quantile)

    def _probe_starts(self, target: np.ndarray) -> np.ndarray:
        """The ``probe_starts`` states of the probe grid (``probe_grid``
        phases per joint over a full turn, sensed once per change) that sense
        most like ``target``: starts far from every known POV, for targets
        a turn of the object moved out of reach of local searches."""
        p = self.params
        if getattr(self, "_probe_event", None) != self._event:
            axis = np.linspace(-np.pi, np.pi, p.probe_grid, endpoint=False)
            grid = np.stack(np.meshgrid(*[axis] * self.n_motors, indexing="ij"), -1)
            grid = grid.reshape(-1, self.n_motors)
            self._body.stage = "compensation"          # its rows are the searches' cost
            self._probe = (grid, finite_rows(self._body.sense(grid), np.inf))
            self._probe_event = self._event
        grid, sensed = self._probe
        distance = np.linalg.norm(sensed - target, axis=1)
        order = np.argsort(distance, kind="stable")[:p.probe_starts]
        return grid[order[np.isfinite(distance[order])]]

    def _sample_povs(self, motor_states: np.ndarray, keep_invalid: bool = False, others=None):
        """Sample the POVs of ``motor_states`` (one batch) and store the valid
        ones. Returns their indices and sensations; with ``keep_invalid``,
        one entry per state (-1 / None for an invalid POV). ``others[i]``:
        further solutions of state ``i``'s sensation (0-D POVs)."""
        p = self.params
        self._body.stage = "pov"
        walk = self._walk_povs(motor_states)
        whole = self._whole_on_level_set(walk)
        indices, sensations = [], []
        for i in range(len(motor_states)):
            # Nothing non-finite becomes a POV (a walk through lost rows).
            if walk.valid[i] and whole[i] and np.all(np.isfinite(walk.samples[i])) and \
                    np.all(np.isfinite(walk.target_sensations[i])):
                samples = walk.samples[i]
                if others is not None and len(others[i]):
                    samples = isolated_samples(np.vstack([motor_states[i:i + 1], others[i]]),
                                               self.n_samples)
                known = self._walked_pose(samples[0])
                if known >= 0:          # a pose walked before (in this batch too)
                    indices.append(known)
                    sensations.append(walk.target_sensations[i])
                    continue
                indices.append(self._store.append(samples))
                self.pov_queries.append(int(walk.queries[i]))
                self.pov_events.append(self._event)
                sensations.append(walk.target_sensations[i])
            else:
                if walk.reason[i] == SPLIT and p.remember_split_povs:
                    self._split_states = np.vstack([self._split_states, motor_states[i]])
                if keep_invalid:
                    indices.append(-1)
                    sensations.append(None)
        return indices, sensations

    def _walk_noise(self) -> float:
        """The noise a POV walk allows for in its corrections: the measured
        one with an ``AveragedStep`` (0 otherwise: exact Gauss-Newton steps)."""
        return float(self.structure.noise) if isinstance(self._fd_step, AveragedStep) else 0.0

    def _walk_budget(self) -> int:
        """Rows a POV walk may sense: ``pov_max_queries``; with an
        ``AveragedStep`` as many calls as that buys with a forward stencil
        (each stencil row is sensed ``repeats`` times)."""
        if not isinstance(self._fd_step, AveragedStep):
            return self.params.pov_max_queries
        return int(self.params.pov_max_queries * stencil_rows(self.n_motors,
                                                              walk_step(self._fd_step))
                   / (self.n_motors + 1))

    def _walk_povs(self, motor_states: np.ndarray):
        """The walks of ``_sample_povs``: ``sample_sensory_points_of_view``
        with the agent's parameters."""
        p = self.params
        return sample_sensory_points_of_view(
            self._body, motor_states, rank=self.structure.pose_rank, n_samples=self.n_samples,
            fd_step=walk_step(self._fd_step), initial_step=p.pov_initial_step,
            min_step=p.pov_min_step, max_step=p.pov_max_step, predictor_tol=p.pov_predictor_tol,
            rank_ratio=p.rank_ratio, max_queries=self._walk_budget(),
            polish_iterations=p.pov_polish_iterations, closure_tol=p.pov_closure_tol,
            sample_tol=p.pov_sample_tol,
            surface_step=p.pov_surface_step, surface_max_queries=p.pov_surface_max_queries,
            min_singular=self._tol.min_singular,
            pattern_ratio=p.pattern_ratio, noise_sd=self._walk_noise())


# How many times what two sensings of one pose differ by a POV's sample may
# lie from its start's sensation: the walk's own tolerances are motor steps
# (``pov_sample_tol``), which leave a residual along the strong pose
# directions several times the noise; a slide to another pose leaves more.
SLID = 4.0


def _distinct(states: np.ndarray, tol: float) -> np.ndarray:
    """The rows of ``states`` farther than ``tol`` (in the torus of phases)
    from every earlier kept row, in order."""
    kept = []
    for row in states:
        if all(np.linalg.norm(wrap_phase(row - k)) > tol for k in kept):
            kept.append(row)
    return np.asarray(kept).reshape(-1, states.shape[1])


def _group_rows(rows: np.ndarray, tol: float) -> np.ndarray:
    """Label rows so that rows within ``tol`` of each other share a label."""
    labels = np.full(len(rows), -1)
    n = 0
    for i in range(len(rows)):
        if labels[i] >= 0:
            continue
        same = (labels < 0) & (np.linalg.norm(rows - rows[i], axis=1) <= tol)
        labels[same] = n
        n += 1
    return labels
