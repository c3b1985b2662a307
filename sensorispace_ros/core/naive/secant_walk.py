"""A loop walk that measures its Jacobian only every few knots.

``LoopWalk`` senses the finite-difference stencil of every probe (``M + 1``
rows) to correct it back onto the level set and to find the tangent there.
Along a smooth loop the sensory Jacobian changes little from one knot to
the next, so ``SecantLoopWalk`` senses the stencil of a front's probe once
every ``refresh_calls`` calls and in between only the probe itself (one
row): its Jacobian is the last knot's, updated along the step by Broyden's
rank-one secant update, with the last knot taken on the level set (it was
corrected there)::

    J' = J + (r - J d) d^T / (d^T d),   d = probe - knot,   r = s(probe) - target

The secant keeps the tangent's turn between the two knots (half of it)
where the stale Jacobian would keep none. A probe whose correction exceeds
the walk's ``predictor_tol`` (the loop bends faster there than the steps
follow, and a secant Jacobian may carry the front onto another stretch of
the level set) makes its front's next probe a measured one. Only
for a noiseless walk with a one-sided stencil and one probe per call;
otherwise every probe has its stencil, as in ``LoopWalk``.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.jacobians import jacobian_stencil, stencil_jacobian
from sensorispace_ros.core.naive.loop_walk import (LoopWalk, _correction_and_null,
                                                   _correction_size, _orient)

__all__ = ["SecantLoopWalk", "secant_update"]


def secant_update(jacobians: np.ndarray, steps: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """Broyden's update of ``jacobians`` ``(B, S, M)`` along ``steps``
    ``(B, M)`` so that each maps its step to its ``residuals`` ``(B, S)``
    (the sensory change the step made); unchanged across any other direction."""
    steps = np.asarray(steps, dtype=float)
    length2 = np.einsum("bm,bm->b", steps, steps)
    miss = residuals - np.einsum("bsm,bm->bs", jacobians, steps)
    with np.errstate(divide="ignore", invalid="ignore"):
        update = np.einsum("bs,bm->bsm", miss, steps) / length2[:, None, None]
    return jacobians + np.where(length2[:, None, None] > 0, update, 0.0)


class SecantLoopWalk(LoopWalk):
    """``LoopWalk`` whose fronts sense their stencil every ``refresh_calls``
    calls and take a secant Jacobian in between (module docstring)."""

    def __init__(self, body, start, *, refresh_calls: int, **walk_parameters):
        super().__init__(body, start, **walk_parameters)
        if int(refresh_calls) < 1:
            raise ValueError(f"refresh_calls: must be an integer >= 1, got {refresh_calls!r}")
        self.refresh_calls = int(refresh_calls)
        # Calls since each POV's front last sensed its stencil.
        self.stale = np.zeros((len(start), 2), dtype=int)

    def _secant_applies(self) -> bool:
        return (self.n_knots == 1 and self.refresh_calls > 1 and self.noise_sd <= 0
                and self.repeats == 1 and self.rows_per_state == self.n_motors + 1)

    def _probe(self):
        if not self._secant_applies():
            return super()._probe()
        point, direction, bend, spacing = self.point, self.direction, self.bend, self.spacing
        active = self.active
        predicted = point + spacing[..., None] * direction + (0.5 * spacing ** 2)[..., None] * bend
        measured = self.stale[active] >= self.refresh_calls - 1                  # (A, 2)
        stencil = jacobian_stencil(predicted[measured], self.fd_step)
        answer = np.asarray(self.body.sense(np.concatenate([stencil, predicted[~measured]])),
                            dtype=float)
        self.calls += 1
        self.queries[active] += np.where(measured, self.rows_per_state, 1).sum(axis=1)
        n_stencil_rows = len(stencil)
        target = np.broadcast_to(self.target[active][:, None, :], point.shape[:2]
                                 + (self.target.shape[1],))
        sensation = np.empty(target.shape)
        jac = np.empty(self.point_jac.shape)
        sensation[measured], jac[measured] = stencil_jacobian(
            answer[:n_stencil_rows].reshape(-1, self.rows_per_state, answer.shape[1]),
            self.fd_step)
        sensation[~measured] = answer[n_stencil_rows:]
        jac[~measured] = secant_update(self.point_jac[~measured],
                                       predicted[~measured] - point[~measured],
                                       sensation[~measured] - target[~measured])
        correction, null = _correction_and_null(
            jac.reshape((-1,) + jac.shape[2:]), (sensation - target).reshape(-1, target.shape[-1]),
            self.rank)
        correction, null = correction.reshape(predicted.shape), null.reshape(predicted.shape)
        size = _correction_size(correction)
        _orient(null, direction + spacing[..., None] * bend)
        knots = predicted + correction
        null[~measured], jac[~measured] = _chord_tangent(
            knots[~measured] - point[~measured], direction[~measured], jac[~measured])
        # A front whose correction exceeds what the walk aims at is where the
        # loop bends faster than its steps follow: its next probe is measured.
        steady = size <= self.predictor_tol
        self.stale[active] = np.where(steady, np.where(measured, 0, self.stale[active] + 1),
                                      self.refresh_calls)
        return jac[:, :, None], null[:, :, None], size[:, :, None], knots[:, :, None]


def _chord_tangent(chords: np.ndarray, tangents: np.ndarray, jacobians: np.ndarray):
    """The tangent at the far end of each chord ``(B, M)`` of a curve whose
    tangent at the near end is ``tangents`` (unit): the near one reflected
    across the chord, as on a circle through both ends (second order in the
    chord's length). Returns it and ``jacobians`` with it as their null
    vector (their action along it removed)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = chords / np.linalg.norm(chords, axis=-1, keepdims=True)
    far = 2.0 * np.sum(unit * tangents, axis=-1, keepdims=True) * unit - tangents
    far = np.where(np.all(np.isfinite(far), axis=-1, keepdims=True), far, tangents)
    along = np.einsum("bsm,bm->bs", jacobians, far)
    return far, jacobians - np.einsum("bs,bm->bsm", along, far)
