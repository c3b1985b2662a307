"""The brief POV walks of the agent in a world that does not wait for it
(``ClockedAgent``).

A walk a change cuts is lost, and the longer it takes the likelier that is:
the clocked agent walks its 1-D POVs with ``points_of_view.brief_loop_walks``
(knots aimed at a coarser correction and taken as corrected, one probe per
front and call reaching as far as the full walk's, a few of its samples
checked), with the noise it measured as the full walk has it. Where noise
sized its tolerances every sample of a walk is sensed again and held to the
start's sensation (``SearchAndSample._whole_on_level_set``); a brief walk's
unchecked samples lie where its spline put them, about as far off the level
set as its checked ones before their step, which a noise far below that does
not cover. POVs of other dimensions are walked as in lockstep.
"""
from __future__ import annotations

from sensorispace_ros.core.naive.noise import walk_step
from sensorispace_ros.core.naive.points_of_view import KNOTS_PER_STEP, brief_loop_walks
from sensorispace_ros.core.naive.searching import SLID

__all__ = ["BriefWalks"]


class BriefWalks:
    """Mixin of ``ClockedAgent``: needs its ``params``, ``structure``,
    ``_body``, ``_fd_step``, ``_tol``, ``_noisy``, ``n_samples`` and the walk
    budget and noise of ``SearchAndSample``."""

    def _walk_povs(self, motor_states):
        """1-D POVs walked briefly, with the noise the agent measured as the
        full walk has it (its step, budget and corrections); secant knots only
        where noise sized none of its tolerances (a secant takes the noise of
        two sensings for slope); other dimensions as the lockstep agent."""
        if not self._walks_briefly():
            return super()._walk_povs(motor_states)
        p = self.params
        # A call reaches as far as the full walk's: fewer probes, each farther apart.
        max_step = p.pov_max_step * KNOTS_PER_STEP / p.clock_pov_knots_per_step
        return brief_loop_walks(
            self._body, motor_states, rank=self.structure.pose_rank, n_samples=self.n_samples,
            fd_step=walk_step(self._fd_step), initial_step=min(p.pov_initial_step, max_step),
            min_step=min(p.pov_min_step, max_step), max_step=max_step,
            predictor_tol=max(p.clock_pov_predictor_tol, p.pov_predictor_tol),
            knots_per_step=p.clock_pov_knots_per_step,
            max_queries=self._walk_budget(), closure_tol=p.pov_closure_tol,
            checks=(p.rank_ratio, self._tol.min_singular, p.pattern_ratio),
            polish_iterations=p.clock_pov_polish_iterations,
            checked_samples=p.clock_pov_checked_samples, noise_sd=self._walk_noise(),
            secant_calls=1 if self._noisy else p.clock_pov_secant_calls)

    def _level_set_allowance(self, walk, n_samples: int, n_sensors: int) -> float:
        """``SearchAndSample._level_set_allowance``, and for a brief walk at
        least ``SLID`` times the largest residual its checked samples had
        before their step: the others stay where its spline put them, about as
        far off the level set (below the noise this agent may have measured)."""
        allowance = super()._level_set_allowance(walk, n_samples, n_sensors)
        if not self._walks_briefly():
            return allowance
        return max(allowance, (SLID * float(walk.max_residual)) ** 2)

    def _walks_briefly(self) -> bool:
        """Its POVs are loops and it walks them briefly (``clock_brief_walk``)."""
        return self.structure.pov_dim == 1 and self.params.clock_brief_walk
