"""The POV walk of an agent whose world does not wait (``ClockedAgent``).

A walk the world changes under is lost (its rows saw two worlds), and the
chance of that grows with the rows it takes: on a row clock a cheaper walk
is both cheaper and more often whole. ``brief_loop_walks`` is
``points_of_view``'s 1-D walk (``loop_walk.LoopWalk``) with fewer rows:

* its knots are ``predictor_tol`` apart in correction, a tolerance the
  caller may set larger than the lockstep walk's (``naive.clock_pov_predictor_tol``):
  fewer, longer steps;
* the knots are taken as the walk corrected them (no polishing call: that
  pass only evens the samples' spacing along the loop);
* the samples get ``polish_iterations`` Gauss-Newton steps with the
  Jacobian of their nearest knot and no repair with fresh Jacobians: a
  sample a step off the level set is still on its POV to the step's size.

Its POVs are the same level sets, sampled a little less evenly and a little
less exactly; the lockstep agent keeps the full walk.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.jacobians import VALID, SensoryPointsOfView
from sensorispace_ros.core.naive.loop_walk import LoopWalk


def brief_loop_walks(body, start, *, rank: int, n_samples: int, fd_step, initial_step: float,
                     min_step: float, max_step: float, predictor_tol: float, max_queries: int,
                     closure_tol: float, checks: tuple, polish_iterations: int = 1,
                     knots_per_step: int = 4, min_loop_length: float = 0.3
                     ) -> SensoryPointsOfView:
    """1-D POVs of ``start`` ``(P, M)`` (module docstring); ``checks`` the
    start's rank test ``(rank_ratio, min_singular, pattern_ratio)``."""
    start = np.array(start, dtype=float, copy=True)
    walk = LoopWalk(body, start, rank=rank, fd_step=fd_step, min_step=min_step,
                    max_step=max_step, predictor_tol=predictor_tol, max_queries=max_queries,
                    min_loop_length=min_loop_length, knots_per_step=knots_per_step,
                    closure_tol=closure_tol)
    walk.begin(*checks, initial_step)
    while len(walk.active):
        walk.advance()
    samples = walk.resample(n_samples, polish_knots=False)
    max_residual = walk.project(samples, polish_iterations)
    reason = walk.reason
    return SensoryPointsOfView(samples=samples, valid=np.array([r == VALID for r in reason]),
                               reason=reason, queries=walk.queries, steps=walk.steps,
                               calls=walk.calls, max_residual=max_residual,
                               target_sensations=walk.target)
