"""The spreads the naive agent reads its sensory noise from (``noise.measure_noise``).

One ``sense`` call holds repeats of one motor state and short lines
through it on a ladder of steps. Their spreads, each robust (median
absolute deviation: heavy tails, wild outputs and lost rows do not move
it): of the repeats, the random part of the noise; of second differences
along the finest informative line, the random part and whatever repeats
exactly (rounding); and the lattice rounded outputs lie on.

Where repeats and ladder see one random noise (their variances agree by an
F test) the two are pooled into a sharper estimate (``random_noise``):
each is the plain variance of its values within ``_CLIP`` robust sds of
their centre, about twice as efficient as the median absolute deviation
under Gaussian noise, and near the true sd under heavy tails, which the
median absolute deviation reads low. Where they disagree the larger
robust spread stands, as it must under rounding the repeats do not see.
"""
from __future__ import annotations

import numpy as np
from scipy.stats import f as f_distribution

from sensorispace_ros.core.naive.repeat_step import robust_sd

__all__ = ["across_range_sd", "clipped_variance", "informative_d2", "ladder_spread",
           "ladder_steps", "line_slope", "noise_rows", "output_lattice", "random_noise",
           "repeat_spread"]

# Fixed direction of the ladder's lines (any body's motor space).
_GOLDEN = 0.5 * (1.0 + np.sqrt(5.0))


def ladder_steps() -> np.ndarray:
    """Line steps (phase) of the ladder: half decades from 1e-8 to 0.1."""
    return 10.0 ** np.arange(-8.0, -0.99, 0.5)


def noise_rows(center: np.ndarray, repeats: int, line_rows: int) -> np.ndarray:
    """The rows ``measure_noise`` senses: ``repeats`` copies of ``center``,
    then one line of ``line_rows`` states per ladder step."""
    center = np.asarray(center, dtype=float).reshape(-1)
    direction = np.cos(2.0 * np.pi * ((np.arange(1, len(center) + 1) * _GOLDEN) % 1.0))
    direction /= np.linalg.norm(direction)
    k = np.arange(line_rows)[None, :, None]
    lines = center + ladder_steps()[:, None, None] * k * direction
    return np.vstack([np.repeat(center[None], repeats, axis=0),
                      lines.reshape(-1, len(center))])


def repeat_spread(repeats: np.ndarray) -> float:
    """Robust sd of sensations of one motor state sensed ``R`` times ``(R, S)``
    (non-finite rows left out), corrected for the median's own spread."""
    rows = repeats[np.all(np.isfinite(repeats), axis=1)]
    if len(rows) < 3:
        return 0.0
    spread = robust_sd(rows - np.median(rows, axis=0))
    return spread * np.sqrt(len(rows) / (len(rows) - 1.0))


def informative_d2(lines: np.ndarray) -> np.ndarray | None:
    """Second differences ``(K - 2, S')`` along the finest informative line
    of the ladder ``(L, K, S)``, over the outputs that move along it (finite
    rows only); steps where most of them are 0 (outputs within one rounding
    step) are skipped. None if no step is informative."""
    d2 = lines[:, 2:] - 2.0 * lines[:, 1:-1] + lines[:, :-2]
    for step in range(len(lines)):
        line = lines[step]
        finite = np.all(np.isfinite(line), axis=1)
        moving = np.ptp(line[finite], axis=0) > 0 if finite.sum() >= 3 else np.zeros(0, bool)
        if not moving.any():
            continue
        values = d2[step][:, moving]
        values = values[np.all(np.isfinite(values), axis=1)]
        # "Unchanged" up to the round-off of the subtraction itself.
        tiny = 16.0 * np.finfo(float).eps * np.max(np.abs(line[finite]))
        if len(values) == 0 or np.mean(np.abs(values) <= tiny) > 0.5:
            continue
        return values
    return None


def ladder_spread(lines: np.ndarray) -> float:
    """The noise seen by second differences along the ladder's lines
    ``(L, K, S)``: ``robust_sd(d2) / sqrt(6)`` at the finest informative
    step (``informative_d2``); 0 if none is."""
    values = informative_d2(lines)
    return 0.0 if values is None else robust_sd(values) / np.sqrt(6.0)


# A lattice finer than this share of the outputs' size is rounding of the
# float kind (float32's relative step is 6e-8): the finite-difference path
# sized from the ladder already lives with it.
_FINEST_LATTICE = 2.0 ** -20
# Share of the gaps between a receptor's values that must be whole
# multiples of the smallest one for the outputs to lie on a lattice.
_ON_LATTICE = 0.95


def output_lattice(sensed: np.ndarray) -> float:
    """The step of the lattice the outputs ``(N, S)`` lie on, 0 if none: the
    median over receptors (with at least three distinct finite values) of
    the smallest gap between two of its values, when the gaps between the
    values of every receptor are whole multiples of it (``_ON_LATTICE`` of
    them) and it is coarser than float rounding (``_FINEST_LATTICE``)."""
    values = np.asarray(sensed, dtype=float)
    smallest, gaps = [], []
    for column in values.T:
        distinct = np.unique(column[np.isfinite(column)])
        if len(distinct) >= 3:
            step = np.diff(distinct)
            smallest.append(step.min())
            gaps.append(step)
    if not smallest:
        return 0.0
    quantum = float(np.median(smallest))
    finite = values[np.isfinite(values)]
    if quantum <= _FINEST_LATTICE * float(np.max(np.abs(finite))):
        return 0.0
    ratio = np.concatenate(gaps) / quantum
    on = np.abs(ratio - np.round(ratio)) <= 1e-3
    return quantum if np.mean(on) >= _ON_LATTICE else 0.0


def line_slope(lines: np.ndarray) -> float:
    """Largest ``|y_last - y_0| / length`` of the ladder's lines ``(L, K, S)``
    with steps of at least 1e-3 (finite ends only; 0 if none)."""
    slopes = [0.0]
    for step, line in zip(ladder_steps(), lines):
        finite = np.flatnonzero(np.all(np.isfinite(line), axis=1))
        if step >= 1e-3 and len(finite) >= 2:
            slopes.append(float(np.linalg.norm(line[finite[-1]] - line[finite[0]])
                                / (step * (finite[-1] - finite[0]))))
    return max(slopes)


# Values beyond this many robust sds of their centre are wild, not noise.
_CLIP = 5.0
# Second differences of independent noise correlate with their neighbours
# (-4/6 and 1/6): their mean square has the spread of 36/70 as many
# independent squares.
_D2_DOF_SHARE = 36.0 / 70.0
# Two variances are one noise unless their ratio lies beyond this quantile
# of the F distribution either way.
_AGREE = 0.999


def clipped_variance(values: np.ndarray, centred: bool) -> tuple[float, float]:
    """``(variance, degrees of freedom)`` of ``values`` ``(K, S)`` within
    ``_CLIP`` robust sds: about each column's mean with ``centred`` (ddof 1
    per column), else about 0 (differences whose mean is 0). ``(0, 0)``
    where the values do not spread."""
    values = np.asarray(values, dtype=float)
    centre = np.nanmedian(values, axis=0) if centred else np.zeros(values.shape[1])
    scale = robust_sd(values - centre)
    if scale == 0.0:
        return 0.0, 0.0
    total, dof = 0.0, 0.0
    for column, c in zip(values.T, centre):
        kept = column[np.isfinite(column) & (np.abs(column - c) <= _CLIP * scale)]
        if centred and len(kept) >= 2:
            total += float(np.sum((kept - kept.mean()) ** 2))
            dof += len(kept) - 1.0
        elif not centred:
            total += float(np.sum(kept ** 2))
            dof += len(kept)
    return (total / dof, dof) if dof else (0.0, 0.0)


def random_noise(repeats: np.ndarray, lines: np.ndarray) -> tuple[float, float, float] | None:
    """``(sd, repeat sd, ladder sd)`` of one random noise that the repeats
    ``(R, S)`` and the ladder's lines ``(L, K, S)`` agree on (an F test at
    ``_AGREE`` either way), the sd pooled by their degrees of freedom; None
    where either does not spread or they disagree."""
    rows = repeats[np.all(np.isfinite(repeats), axis=1)]
    d2 = informative_d2(lines)
    if len(rows) < 3 or d2 is None:
        return None
    repeat_var, repeat_dof = clipped_variance(rows, centred=True)
    ladder_var, ladder_dof = clipped_variance(d2, centred=False)
    ladder_var, ladder_dof = ladder_var / 6.0, ladder_dof * _D2_DOF_SHARE
    if repeat_var <= 0.0 or ladder_var <= 0.0:
        return None
    if ladder_var > repeat_var * f_distribution.ppf(_AGREE, ladder_dof, repeat_dof) or \
            repeat_var > ladder_var * f_distribution.ppf(_AGREE, repeat_dof, ladder_dof):
        return None
    pooled = (repeat_dof * repeat_var + ladder_dof * ladder_var) / (repeat_dof + ladder_dof)
    return float(np.sqrt(pooled)), float(np.sqrt(repeat_var)), float(np.sqrt(ladder_var))


def across_range_sd(repeats: np.ndarray, jac: np.ndarray, rank: int) -> float:
    """Per-receptor sd of the repeats ``(B, R, S)`` of ``B`` motor states
    outside the ``rank`` leading left singular directions of their
    Jacobians ``(B, S, M)``: the receptors' own noise. A joint that lands
    off its command moves the sensation along the Jacobian's range
    (``J delta``, to first order), so only this part can fake a pose
    direction the sensation does not follow. Rows with a lost value and
    states without a Jacobian (all zero) are left out; 0 where no state
    has two repeats or nothing lies outside the range."""
    repeats, jac = np.asarray(repeats, dtype=float), np.asarray(jac, dtype=float)
    n_sensors = repeats.shape[-1]
    usable = np.any(jac != 0, axis=(1, 2)) & np.all(np.isfinite(jac), axis=(1, 2))
    if rank >= n_sensors or not usable.any():
        return 0.0
    repeats, jac = repeats[usable], jac[usable]
    finite = np.all(np.isfinite(repeats), axis=2, keepdims=True)
    count = np.sum(finite, axis=1)
    values = np.where(finite, repeats, 0.0)
    mean = values.sum(axis=1, keepdims=True) / np.maximum(count, 1)[:, None]
    deviation = np.where(finite, values - mean, 0.0)
    inside = np.einsum("brs,bsk->brk", deviation, np.linalg.svd(jac)[0][:, :, :rank])
    dof = float(np.sum(np.maximum(count - 1, 0))) * (n_sensors - rank)
    if dof <= 0:
        return 0.0
    return float(np.sqrt(max(np.sum(deviation ** 2) - np.sum(inside ** 2), 0.0) / dof))
