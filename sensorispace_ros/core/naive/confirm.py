"""A compensation accepted against the measured noise, not a fixed threshold.

A search (``compensation.compensate``) ends where one sensing of its state
is as close to the target as one sensing's noise allows. Along the pose's
weakest direction that noise hides a displacement of ``noise /
weakest singular value``; with a target sensed once, a state a lattice step
away can pass. Where the agent measured noise it senses the search's end
``repeats`` times (with its Jacobian stencil, in one call) and averages.
The part of the residual that no pose change explains (outside the range of
the Jacobian's ``rank`` directions) must be what the noise of the average
and of the target explains (``|r_perp|^2 / variance`` is chi-square with
``S - rank`` degrees of freedom); the part inside is the pose error: a
Gauss-Newton step with the averaged residual removes it, and the state is
sensed again until what is left there is noise too (``rounds`` at most).
The search is coarse with single sensings; its end is refined with
averages. Anchors (sensations at rest) are averaged as often
(``NaiveAgent._rest_sensation``), so the test is tight where the agent can
afford it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive.jacobians import (SymmetricStep, halved, jacobian_stencil,
    minimum_norm_correction, stencil_bend, stencil_jacobian, stencil_rows)


def finite_mean(rows: np.ndarray) -> np.ndarray:
    """Mean of the finite rows of ``rows`` ``(R, S)`` (NaN if none is)."""
    rows = np.asarray(rows, dtype=float)
    finite = np.all(np.isfinite(rows), axis=1)
    if not finite.any():
        return np.full(rows.shape[1], np.nan)
    return rows[finite].mean(axis=0)


def confirm_compensations(body, states: np.ndarray, targets: np.ndarray,
                          target_variance: np.ndarray, *, noise_sd: float, repeats: int,
                          rank: int, fd_step: float, confidence: float, rounds: int = 3,
                          max_error: float = np.inf, max_step: float | None = None,
                          min_singular: float = 0.0):
    """Refine every state of ``states`` ``(K, M)`` toward its target
    ``targets`` ``(K, S)`` with averaged sensings and accept it only where
    what is left of the residual is noise.

    A round senses each pending state with its Jacobian stencil and
    ``repeats - 1`` more times (one call for all of them) and averages. The
    residual's part outside the Jacobian's ``rank`` directions is what no pose
    change explains: beyond the ``confidence`` quantile of ``target_variance``
    ``(K,)`` (per receptor) plus the average's ``noise_sd^2 / repeats`` the
    state is rejected. Its part inside them is the pose error: within what the
    noise of two averages explains, the state is accepted after one
    Gauss-Newton step with the averaged residual; beyond it the state takes that
    step and is sensed again in the next round. ``rounds`` rounds at most
    (then rejected). ``max_error``: the largest predicted pose error (one
    standard deviation, motor space, phases) accepted: the noise of the target
    and of the average over the Jacobian's ``rank``-th singular value, the
    longest axis of ``variance (J^T J)^+``; a state whose pose the noise
    does not pin that well is rejected, and so is one whose Jacobian's
    ``rank``-th singular value is not above ``min_singular`` (its noise's
    expected spectral norm: a pose where the eye sees no light senses alike
    wherever it lies); with such a floor and a central step, a settled
    state's ``rank``-th singular value must also hold at half the step
    (``_slope_holds``). ``max_step`` (motor, phases): a state whose
    Gauss-Newton step is within it is settled whatever its residual in range
    (a known POV tested against an anchor: its pose is where it was found,
    not refined). The rounds take a search's end, as close to its target as
    one sensing tells, to what the averages tell.

    Returns ``(refined states (K, M), accepted (K,) bool, averaged
    sensations at the last round (K, S))``."""
    states = np.asarray(states, dtype=float)
    n_states, n_sensors = len(states), targets.shape[1]
    refined = states.copy()
    accepted = np.zeros(n_states, bool)
    means = np.full((n_states, n_sensors), np.nan)
    variances, limits = _noise_bounds(target_variance, noise_sd, repeats, confidence,
                                      n_sensors, rank)
    pending = np.arange(n_states)
    for _ in range(int(rounds)):
        if not len(pending):
            break
        mean, jac, whole, _ = averaged_with_jacobian(body, refined[pending], repeats,
                                                     fd_step)
        means[pending] = mean
        step, explained, settled = _judge(jac, mean - targets[pending], rank, whole,
                                          [v[pending] for v in variances], limits,
                                          (max_error, min_singular), max_step)
        if min_singular > 0 and isinstance(fd_step, SymmetricStep) and settled.any():
            bent = _bent(body, refined[pending], jac, rank, fd_step, settled)
            explained, settled = explained & ~bent, settled & ~bent
        refined[pending[explained]] += step[explained]
        accepted[pending[settled]] = True
        pending = pending[explained & ~settled]
    refined[~accepted] = states[~accepted]
    return refined, accepted, means


def verify_matches(body, states: np.ndarray, targets: np.ndarray,
                   target_variance: np.ndarray, *, noise_sd: float, repeats: int, rank: int,
                   fd_step: float, confidence: float, max_error: float, max_step: float,
                   min_singular: float = 0.0, discrepancy: float = 0.0, sensed=None):
    """Known POVs ``states`` ``(K, M)`` matched by a sweep to the rows
    ``targets`` ``(K, S)`` of one snapshot (per-receptor variance
    ``target_variance`` ``(K,)``), each sensed ``repeats`` times with its
    Jacobian stencil in one call. Returns two verdicts ``(K,)``:

    * ``precise``: one round of ``confirm_compensations`` with ``max_step``:
      the match is a compensation whose pose the noise pins within
      ``max_error``;
    * ``located``: the POV is the one the row sensed, to what the noise of
      the row lets any test tell: its fresh average reproduces the target
      within the ``confidence`` quantile of chi-square with ``S`` degrees of
      freedom (the variance of the two plus ``discrepancy``, what matched
      POVs differ by beyond their noise: ``match_discrepancy``), its
      Jacobian's ``rank``-th singular value stands above
      ``min_singular``, and the located matches of the snapshot together
      pass the same test with ``S`` degrees of freedom per match, or none
      is located (``pooled_within_noise``): every row of one snapshot moved
      by one displacement, so an error they share shows in their sum by the
      square root of their number where each alone hides it.

    A single sensing of the row leaves the pose along its weakest direction
    uncertain by more than ``max_error`` where the noise is large: such a
    match is never precise, yet located it shows the light layout unchanged
    and which known POVs neighbour the rows it did not match. ``sensed``: a
    list that receives ``(mean, Jacobian, whole, bend)`` of ``states``."""
    states = np.asarray(states, dtype=float)
    targets = np.asarray(targets, dtype=float)
    n_sensors = targets.shape[1]
    mean, jac, whole, bend = averaged_with_jacobian(body, states, repeats, fd_step)
    if sensed is not None:
        sensed.append((mean, jac, whole, bend))
    residual = mean - targets
    variances, limits = _noise_bounds(target_variance, noise_sd, repeats, confidence,
                                      n_sensors, rank)
    _, _, precise = _judge(jac, residual, rank, whole, variances, limits,
                           (max_error, min_singular), max_step)
    singular = np.linalg.svd(jac, compute_uv=False)[:, rank - 1]
    with np.errstate(invalid="ignore"):
        statistic = np.sum(residual ** 2, axis=1) / (variances[0] + discrepancy)
    alone = whole & np.isfinite(statistic) & (singular > min_singular) & \
        (statistic <= chi2.ppf(confidence, n_sensors))
    return precise, pooled_within_noise(statistic, alone, n_sensors, confidence)


def pooled_within_noise(statistic: np.ndarray, candidates: np.ndarray, dof: int,
                        confidence: float) -> np.ndarray:
    """The ``candidates`` ``(K,)`` bool if their chi-square ``statistic``
    (``dof`` degrees of freedom each where the hypothesis holds) sum within
    the ``confidence`` quantile of chi-square with ``dof`` per candidate,
    else none: each passed alone, so an excess of the sum is spread over
    them (an error they share), not one outlier to drop."""
    keep = np.asarray(candidates, dtype=bool)
    total = float(np.sum(np.asarray(statistic, dtype=float)[keep]))
    if keep.any() and total > chi2.ppf(confidence, dof * int(keep.sum())):
        return np.zeros_like(keep)
    return keep.copy()


def _judge(jac, residual, rank, whole, variances, limits, bounds, max_step):
    """One round of ``confirm_compensations``: the Gauss-Newton step of each
    state, whether the noise explains its residual outside the Jacobian's
    range (and it pins its pose: ``bounds``, the largest predicted pose
    error and the smallest ``rank``-th singular value), and whether it is
    settled (its step within ``max_step``, or its residual inside the range
    within noise too)."""
    u, singular, _ = np.linalg.svd(jac, full_matrices=False)
    along = np.einsum("bsk,bs->bk", u[:, :, :rank], residual)
    inside = np.sum(along ** 2, axis=1)
    outside = np.sum(residual ** 2, axis=1) - inside
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = np.sqrt(variances[0]) / singular[:, rank - 1]
    step = minimum_norm_correction(jac, residual, rank)
    max_error, min_singular = bounds
    explained = whole & np.isfinite(outside) & (outside <= variances[0] * limits[0]) & \
        (spread <= max_error) & (singular[:, rank - 1] > min_singular) & \
        np.all(np.isfinite(step), axis=1)
    if max_step is None:
        settled = explained & (inside <= variances[1] * limits[1])
    else:
        settled = explained & (np.linalg.norm(step, axis=1) <= max_step)
    return step, explained, settled


def _noise_bounds(target_variance, noise_sd, repeats, confidence, n_sensors, rank):
    """``_judge``'s ``variances`` (of the residual before a step, and of what
    is left in range after one: the difference of two averages of the
    state, the target's noise in both) and chi-square ``limits`` (outside
    the range, inside it)."""
    target_variance = np.asarray(target_variance, dtype=float)
    variances = (target_variance + noise_sd ** 2 / repeats,
                 target_variance + 2.0 * noise_sd ** 2 / repeats)
    limits = (chi2.ppf(confidence, max(n_sensors - rank, 1)), chi2.ppf(confidence, max(rank, 1)))
    return variances, limits


def _bent(body, states, jac, rank, fd_step, settled):
    """``(K,)``: which ``settled`` states' ``rank``-th singular value does not
    hold at half the step (``_slope_holds``)."""
    bent = np.zeros_like(settled)
    bent[settled] = ~_slope_holds(body, states[settled], jac[settled], rank, fd_step)
    return bent


def _slope_holds(body, states, jac, rank, fd_step):
    """True where the ``rank``-th singular value of the Jacobians ``jac``
    ``(K, S, M)`` of ``states`` holds at half the (central) step: at least
    half of it. A direction's slope does not change with the step; the bend
    a central difference sees along a direction the outputs do not follow
    (one light in view) falls with the step's square, to a quarter."""
    _, jac_half, whole, _ = averaged_with_jacobian(body, states, 1, halved(fd_step))
    at_step = np.linalg.svd(jac, compute_uv=False)[:, rank - 1]
    at_half = np.linalg.svd(jac_half, compute_uv=False)[:, rank - 1]
    return whole & (at_half >= 0.5 * at_step)


def averaged_with_jacobian(body, states, repeats, fd_step):
    """Sense ``states`` ``(K, M)`` with their Jacobian stencils and ``repeats -
    1`` more times, in one call. Returns ``(mean sensation (K, S), Jacobian
    (K, S, M), whole (K,), bend (K,))``; a stencil with a lost row has no
    Jacobian (zero, not ``whole``); ``bend`` is ``stencil_bend``'s."""
    n_states, n_motors = states.shape
    rows = stencil_rows(n_motors, fd_step)
    stencil = jacobian_stencil(states, fd_step).reshape(n_states, rows, n_motors)
    extra = np.repeat(states[:, None, :], repeats - 1, axis=1)
    asked = np.concatenate([stencil, extra], axis=1).reshape(-1, n_motors)
    with getattr(body, "fresh", _nothing)():
        sensed = np.asarray(body.sense(asked), dtype=float).reshape(
            n_states, rows + repeats - 1, -1)
    _, jac = stencil_jacobian(sensed[:, :rows], fd_step)
    whole = np.all(np.isfinite(jac), axis=(1, 2))
    jac[~whole] = 0.0
    mean = np.stack([finite_mean(np.concatenate([sensed[k, :1], sensed[k, rows:]]))
                     for k in range(n_states)])
    return mean, jac, whole, stencil_bend(sensed[:, :rows], fd_step)


@dataclass
class Provisional:
    """A compensation (``record``: found at its ``event`` for the anchor of
    the snapshot of its ``anchor_event``) of an anchor no sweep row
    confirmed: only the anchor's sensation tells it from a far pose sensing
    it alike. ``rest_pov``: the POV the arm rested on for that anchor (a row
    of the anchor's snapshot); ``record.pov``: the POV found (a row of the
    snapshot of the event that found it)."""

    record: object
    rest_pov: int


def settle_provisional(pending: list, pool: list, matches, known_comp: dict):
    """Which ``pending`` ``Provisional`` compensations this sweep confirms:
    one known POV now senses both what the anchor's POV sensed then (a sweep
    match of that row of the anchor's snapshot, or a hit of its anchor where
    some of its rows matched) and what the found POV sensed when it was
    found (a match of that row of the later snapshot). The two relative
    poses are then one, which is what the compensation claims, shown by
    matches independent of its search. ``pool``: the snapshots now;
    ``matches`` ``[(before, after), ...]`` theirs; ``known_comp``
    ``{snapshot index: POV}`` the anchors' hits. One whose snapshots left
    the pool can never be confirmed and is dropped. Returns ``(records
    confirmed, still pending)``."""
    index = {snap.event: k for k, snap in enumerate(pool)}
    confirmed, kept = [], []
    for entry in pending:
        then, found = index.get(entry.record.anchor_event), index.get(entry.record.event)
        if then is None or found is None:
            continue
        now = _partner(matches[then], entry.rest_pov)
        if now < 0 and len(matches[then][0]) and then in known_comp:
            now = int(known_comp[then])
        if now >= 0 and now == _partner(matches[found], entry.record.pov):
            confirmed.append(entry.record)
        else:
            kept.append(entry)
    return confirmed, kept


def _partner(match, row: int) -> int:
    """The POV ``match`` ``(before, after)`` pairs with row ``row`` (-1: none)."""
    before, after = match
    hit = np.flatnonzero(np.asarray(before) == row)
    return int(after[hit[0]]) if len(hit) else -1


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
