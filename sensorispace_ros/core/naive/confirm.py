"""A compensation accepted against the measured noise, not a fixed threshold.

A search (``compensation.compensate``) ends where one sensing of its state
is as close to the target as one sensing's noise allows. Along the pose's
weakest direction that noise hides a displacement of ``noise /
weakest singular value``; with a target sensed once, a state a lattice step
away can pass. Where the agent measured noise it senses the search's end
``repeats`` times (with its Jacobian stencil, in one call), averages, takes
one Gauss-Newton step with the averaged residual and accepts the result
only if the part of the residual that no pose change explains (outside the
range of the Jacobian's ``rank`` directions) is what the noise of the
average and of the target explains: ``|r_perp|^2 / variance`` is chi-square
with ``S - rank`` degrees of freedom. Anchors (sensations at rest) are
averaged as often (``NaiveAgent._rest_sensation``), so the test is tight
where the agent can afford it.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive.jacobians import (jacobian_stencil, minimum_norm_correction,
    stencil_jacobian, stencil_rows)


def finite_mean(rows: np.ndarray) -> np.ndarray:
    """Mean of the finite rows of ``rows`` ``(R, S)`` (NaN if none is)."""
    rows = np.asarray(rows, dtype=float)
    finite = np.all(np.isfinite(rows), axis=1)
    if not finite.any():
        return np.full(rows.shape[1], np.nan)
    return rows[finite].mean(axis=0)


def confirm_compensations(body, states: np.ndarray, targets: np.ndarray,
                          target_variance: np.ndarray, *, noise_sd: float, repeats: int,
                          rank: int, fd_step: float, confidence: float):
    """Sense every state of ``states`` ``(K, M)`` with its Jacobian stencil
    and ``repeats - 1`` more times (one call), average, step once toward its
    target ``targets`` ``(K, S)`` and test the residual left outside the
    Jacobian's range against ``target_variance`` ``(K,)`` (per receptor) plus
    the average's ``noise_sd^2 / repeats`` at ``confidence``.

    Returns ``(stepped states (K, M), accepted (K,) bool, averaged
    sensations (K, S))``."""
    states = np.asarray(states, dtype=float)
    n_states, n_motors = states.shape
    if n_states == 0:
        return states.copy(), np.zeros(0, bool), np.zeros((0, targets.shape[1]))
    rows = stencil_rows(n_motors, fd_step)
    stencil = jacobian_stencil(states, fd_step).reshape(n_states, rows, n_motors)
    extra = np.repeat(states[:, None, :], repeats - 1, axis=1)
    asked = np.concatenate([stencil, extra], axis=1).reshape(-1, n_motors)
    with getattr(body, "fresh", _nothing)():
        sensed = np.asarray(body.sense(asked), dtype=float).reshape(n_states, rows + repeats - 1, -1)
    _, jac = stencil_jacobian(sensed[:, :rows], fd_step)
    # A stencil with a lost row has no Jacobian: it confirms nothing.
    whole = np.all(np.isfinite(jac), axis=(1, 2))
    jac[~whole] = 0.0
    mean = np.stack([finite_mean(np.concatenate([sensed[k, :1], sensed[k, rows:]]))
                     for k in range(n_states)])
    residual = mean - targets
    u, _, _ = np.linalg.svd(jac, full_matrices=False)
    along = np.einsum("bsk,bs->bk", u[:, :, :rank], residual)
    outside = np.sum(residual ** 2, axis=1) - np.sum(along ** 2, axis=1)
    variance = np.asarray(target_variance, dtype=float) + noise_sd ** 2 / repeats
    dof = max(targets.shape[1] - rank, 1)
    accepted = np.isfinite(outside) & (outside <= variance * chi2.ppf(confidence, dof))
    accepted &= whole
    step = minimum_norm_correction(jac, residual, rank)
    stepped = states + np.where(accepted[:, None], step, 0.0)
    return stepped, accepted, mean


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
