"""What the naive agent measures of its own body before it explores.

The agent knows its motor values, each joint's period and the sensations
``sense`` returns; nothing about space. The rank ``r`` of the sensory
Jacobian ``J_s = dsense/dm`` at a generic motor state is the number of
degrees of freedom of the sensor's configuration that the sensation sees
(the pose rank), and ``M - r`` is the dimension of a point of view (POV),
the level set ``{m : sense(m) = s}``. Both are measured here, once, at the
start state and a few states around it, in one ``sense`` call.

Decision rule (scale-free). At each probe state the Jacobian is estimated by
central differences at two steps ``h`` and ``2h`` (phases, so ``h`` is a
fixed fraction of each joint's period). Their difference is the
finite-difference noise floor ``f``. The singular values, each raised to at
least ``f``, followed by ``f`` itself, are cut at their largest ratio between
neighbours: the rank is the number of values above the cut, and that ratio
is the probe's gap. A probe whose largest ratio is below ``min_gap`` sees
nothing it could resolve (a blank sensation) and does not vote. The pose
rank is the rank most probes vote for (ties: the larger), ``rank_gap`` the
smallest gap among those probes. Scaling every sensation by a constant
scales the singular values and the floor alike: nothing changes.

The same measurement gives the agent's sensory *gain*: the median largest
singular value (sensation per phase radian). Tolerances on sensations are
motor-equivalent amounts times a gain: the one measured at the state in
question where a Jacobian is at hand, this one elsewhere (``Tolerances``),
so no tolerance is in the units of the receptors.
"""
from __future__ import annotations

import contextlib
import warnings
from dataclasses import dataclass, replace

import numpy as np

from sensorispace_ros.core.naive.jacobians import (CloudStep, cloud_design, cloud_fit,
                                                   jacobian_stencil, stencil_rows)
from sensorispace_ros.core.naive.noise_spread import across_range_sd

# Fixed directions of the probe states around the start (any body's motor
# space): a golden-ratio sequence of cosines, normalised per state.
_GOLDEN = 0.5 * (1.0 + np.sqrt(5.0))


@dataclass(frozen=True)
class BodyStructure:
    """The agent's measurement of itself (``measure_structure``).

    ``pose_rank`` the rank of the sensory Jacobian, ``pov_dim`` the dimension
    of a POV (joints minus rank), ``rank_gap`` the smallest singular-value
    ratio at the cut among the probes that agree, ``gain`` the median
    largest singular value (sensation per phase radian), ``floor`` the
    median finite-difference noise floor (same unit), ``votes`` how many of
    ``probes`` probe states agree; ``noise`` the measured per-receptor
    sensory noise (``noise.SensoryNoise.sd``), ``fd_step`` the
    finite-difference step sized from it, ``weakest`` the median
    ``pose_rank``-th singular value of the agreeing probes; ``repeat_noise``
    the part of the noise a repeat does not repeat (``SensoryNoise.repeat_sd``);
    ``quantum`` the step of the lattice rounded outputs lie on (0: none,
    ``SensoryNoise.quantum``); ``receptor_noise`` the part of the probes'
    repeats across their Jacobians' range (``noise_spread.across_range_sd``,
    0 where not measured): what no joint error explains."""

    n_motors: int
    pose_rank: int
    rank_gap: float
    gain: float
    floor: float
    votes: int
    probes: int
    noise: float = 0.0
    fd_step: float = 0.0
    weakest: float = 0.0
    repeat_noise: float = 0.0
    quantum: float = 0.0
    receptor_noise: float = 0.0

    @property
    def pov_dim(self) -> int:
        return self.n_motors - self.pose_rank

    def metrics(self) -> dict:
        """``naive.*`` numbers of the structure estimate."""
        return {"naive.pose_rank": int(self.pose_rank), "naive.pov_dim": int(self.pov_dim),
                "naive.rank_gap": float(self.rank_gap), "naive.sensory_gain": float(self.gain),
                "naive.fd_noise_floor": float(self.floor),
                "naive.rank_votes": int(self.votes), "naive.rank_probes": int(self.probes),
                "naive.noise_estimate": float(self.noise), "naive.fd_step": float(self.fd_step),
                "naive.noise_quantum": float(self.quantum)}


@dataclass(frozen=True)
class Tolerances:
    """Sensation tolerances of one agent where no Jacobian is at hand (sweep
    matching, grouping targets, the smallest singular value), in the units
    of its sensations: the parameters' motor-equivalent amounts times its
    measured gain. Where a Jacobian is at hand (a search's solution) the
    agent scales by the gain there instead."""

    match: float
    separation: float
    min_singular: float
    noise_step: float = 0.0
    ratio: float = 0.0

    @classmethod
    def of(cls, params, structure: BodyStructure, jacobian_noise: float = 0.0,
           noise_step: float = 0.0, noise_residual: float = 0.0) -> "Tolerances":
        """``jacobian_noise``: the expected spectral norm of a
        finite-difference Jacobian's noise; a rank test's smallest singular
        value stays above it (the r-th singular value of a Jacobian of pure
        noise, a blank sensation's, lies below its first). ``noise_step``:
        the sensory residual measured noise explains, whose Gauss-Newton step
        a search may keep (``compensation.compensate``). ``noise_residual``
        (0: none): what two sensings of one pose differ by at most, where
        noise sized the match tolerance; a match must then stand out by
        ``match_ratio`` from the next nearest sensation and lie beyond this
        residual (``equality_sets.match_sensations``), not by a separation
        tied to the tolerance."""
        # A body that showed nothing (rank 0) has no gain; no sensation of it
        # passes a rank test, so any positive scale will do.
        gain = structure.gain if structure.gain > 0 else 1.0
        separation, ratio = params.match_separation * gain, 0.0
        if noise_residual > 0:
            separation, ratio = noise_residual, params.match_ratio
        return cls(match=params.match_tol * gain, separation=separation,
                   min_singular=max(params.min_singular * gain, jacobian_noise),
                   noise_step=noise_step, ratio=ratio)


def probe_states(center: np.ndarray, count: int, radius: float) -> np.ndarray:
    """``(count, M)``: ``center`` and ``count - 1`` states ``radius`` (phase
    radians) away from it in fixed directions."""
    center = np.asarray(center, dtype=float).reshape(-1)
    k = np.arange(1, count)[:, None]
    j = np.arange(1, len(center) + 1)[None, :]
    direction = np.cos(2.0 * np.pi * ((k * j * _GOLDEN) % 1.0))
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
    return np.vstack([center[None], center + radius * direction])


def central_stencil(states: np.ndarray, step: float) -> np.ndarray:
    """Rows sensed per state: the state, then ``+-h`` and ``+-2h`` along each
    joint, ``(B * (1 + 4M), M)``."""
    states = np.asarray(states, dtype=float)
    n_motors = states.shape[1]
    eye = np.eye(n_motors)
    offsets = np.concatenate([np.zeros((1, n_motors)), step * eye, -step * eye,
                              2 * step * eye, -2 * step * eye])
    return (states[:, None, :] + offsets[None]).reshape(-1, n_motors)


def gap_rank(singular: np.ndarray, floor: np.ndarray):
    """Rank and gap of each row of singular values ``(B, k)`` (descending)
    against its noise floor ``(B,)``: the largest ratio between neighbours
    of ``max(sigma, floor)`` followed by ``floor``. Returns ``(rank (B,),
    gap (B,))``; a row of values all at the floor has gap 1."""
    floor = np.maximum(np.asarray(floor, dtype=float), 1e-300)
    values = np.concatenate([np.maximum(singular, floor[:, None]), floor[:, None]], axis=1)
    log_gap = np.log(values[:, :-1]) - np.log(values[:, 1:])
    cut = np.argmax(log_gap, axis=1)
    return cut + 1, np.exp(log_gap[np.arange(len(values)), cut])


def jacobians_and_floor(sensed: np.ndarray, n_states: int, n_motors: int, step: float,
                        repeats: int = 1, noise_sd: float | None = None):
    """Jacobians ``(B, S, M)`` and their noise floors ``(B,)`` from the rows
    of ``central_stencil`` (each sensed ``repeats`` times in a row, averaged
    over the finite ones).

    Without ``noise_sd`` the Jacobian is the central difference at step
    ``h`` and the floor the larger of the truncation error (the difference
    of the estimates at ``h`` and ``2h``) and float64 round-off. With it
    (the sd left in a row averaged over its repeats, at a step sized from
    measured noise) the Jacobian is the least-squares slope through the
    rows at ``-2h .. 2h`` along each joint (a fifth of the central
    difference's noise variance) and the floor the noise's: the expected
    spectral norm of that slope's noise, ``sd (sqrt(S) + sqrt(M)) /
    (sqrt(10) h)``. Truncation error is then left out: it is smooth in the
    motor state and lies in the range of the Jacobian, so it does not lift
    the singular values of the level set's tangents the rank test looks
    at."""
    rows = np.asarray(sensed, dtype=float).reshape(n_states, 1 + 4 * n_motors, repeats, -1)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)        # all repeats of a row lost
        rows = np.nanmean(np.where(np.isfinite(rows), rows, np.nan), axis=2)
    return stencil_spectrum_inputs(rows, n_motors, step, noise_sd)


def stencil_spectrum_inputs(rows: np.ndarray, n_motors: int, step: float,
                            noise_sd: float | None = None):
    """``jacobians_and_floor`` of the stencil's rows already averaged,
    ``(B, 1 + 4M, S)``."""
    plus, minus = rows[:, 1:1 + n_motors], rows[:, 1 + n_motors:1 + 2 * n_motors]
    plus2, minus2 = rows[:, 1 + 2 * n_motors:1 + 3 * n_motors], rows[:, 1 + 3 * n_motors:]
    jac = np.swapaxes(plus - minus, 1, 2) / (2.0 * step)
    jac2 = np.swapaxes(plus2 - minus2, 1, 2) / (4.0 * step)
    finite = np.all(np.isfinite(jac), axis=(1, 2)) & np.all(np.isfinite(jac2), axis=(1, 2))
    if noise_sd is not None:
        # Least squares through (-2h, -h, h, 2h): (2 J_h + 8 J_2h) / 10.
        jac = 0.2 * jac + 0.8 * jac2
    jac[~finite], jac2[~finite] = 0.0, 0.0
    with np.errstate(invalid="ignore"):
        scale = np.nanmax(np.abs(np.where(np.isfinite(rows), rows, 0.0)), axis=(1, 2))
    rounding = np.finfo(float).eps * scale / step
    if noise_sd is None:
        floor = np.maximum(np.linalg.norm(jac - jac2, ord=2, axis=(1, 2)), rounding)
    else:
        n_sensors = rows.shape[2]
        noise = noise_sd * (np.sqrt(n_sensors) + np.sqrt(n_motors)) / (np.sqrt(10.0) * step)
        floor = np.maximum(rounding, noise)
    # A probe with a lost row has no Jacobian: J = 0 against a floor of 1 has gap 1 (no vote).
    return jac, np.where(finite, floor, 1.0)


def noise_rank(singular: np.ndarray, floor: np.ndarray, factor: float):
    """Rank and gap of each row of singular values ``(B, k)`` against a
    floor ``(B,)`` that is the expected spectral norm of the Jacobian's
    noise: the rank counts the values at least ``factor`` times the floor
    (noise alone stays below it); the gap is the ``rank``-th value over the
    larger of the next one and the floor (1 for rank 0)."""
    floor = np.maximum(np.asarray(floor, dtype=float), 1e-300)
    rank = np.sum(singular >= factor * floor[:, None], axis=1)
    padded = np.concatenate([singular, np.zeros((len(singular), 1))], axis=1)
    rows = np.arange(len(singular))
    above = np.where(rank > 0, padded[rows, np.maximum(rank - 1, 0)], floor)
    below = np.maximum(padded[rows, rank], floor)
    return rank, np.where(rank > 0, above / below, 1.0)


def structure_from_probes(singular: np.ndarray, floor: np.ndarray, n_motors: int,
                          min_gap: float, noise_gap: float | None = None) -> BodyStructure:
    """The vote of ``gap_rank`` over probe states (see the module docstring);
    with ``noise_gap`` (a floor that is the measured noise's) of
    ``noise_rank``, a probe voting when its gap reaches ``noise_gap``."""
    if noise_gap is None:
        rank, gap = gap_rank(singular, floor)
    else:
        rank, gap = noise_rank(singular, floor, noise_gap)
        min_gap = noise_gap
    decided = gap >= min_gap
    if not decided.any():
        return BodyStructure(n_motors, 0, float(np.max(gap, initial=1.0)), 0.0,
                             float(np.median(floor)), 0, len(rank))
    counts = np.bincount(rank[decided], minlength=n_motors + 1)
    pose_rank = int(np.flatnonzero(counts == counts.max())[-1])
    agree = decided & (rank == pose_rank)
    weakest = float(np.median(singular[agree, pose_rank - 1])) if pose_rank > 0 else 0.0
    return BodyStructure(n_motors, pose_rank, float(np.min(gap[agree])),
                         float(np.median(singular[decided, 0])), float(np.median(floor[decided])),
                         int(agree.sum()), len(rank), weakest=weakest)


def probe_rows(body, center: np.ndarray, *, fd_step: float, probes: int, radius: float,
               repeats: int = 1) -> np.ndarray:
    """``central_stencil`` of the ``probes`` probe states around ``center``,
    each row sensed ``repeats`` times in a row, in ONE ``sense`` call:
    ``(probes, 1 + 4M, repeats, S)``."""
    center = np.asarray(center, dtype=float).reshape(-1)
    if int(probes) != probes or probes < 1:
        raise ValueError(f"probes must be an integer >= 1, got {probes}")
    for name, value in (("fd_step", fd_step), ("radius", radius)):
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a finite number > 0, got {value}")
    states = probe_states(center, int(probes), radius)
    stencil = np.repeat(central_stencil(states, fd_step), int(repeats), axis=0)
    sensed = np.asarray(body.sense(stencil), dtype=float)
    return sensed.reshape(len(states), 1 + 4 * len(center), int(repeats), -1)


def measure_structure(body, center: np.ndarray, *, fd_step: float, probes: int = 8,
                      radius: float = 0.1, min_gap: float = 100.0, repeats: int = 1,
                      noise_sd: float | None = None, noise_gap: float = 4.0) -> BodyStructure:
    """Pose rank, POV dimension and sensory gain of ``body`` around
    ``center`` (phases), from ``probes`` states in ONE ``sense`` call of
    ``probes * (1 + 4M) * repeats`` rows. ``noise_sd``: the sd left in a
    row averaged over its ``repeats`` when ``fd_step`` was sized from the
    measured noise (``jacobians_and_floor``); the rank is then
    ``noise_rank``'s at ``noise_gap``."""
    if not np.isfinite(min_gap) or min_gap <= 0:
        raise ValueError(f"min_gap must be a finite number > 0, got {min_gap}")
    sensed = probe_rows(body, center, fd_step=fd_step, probes=probes, radius=radius,
                        repeats=repeats)
    return probe_structure(sensed, fd_step, min_gap, noise_sd, noise_gap)[0]


def probe_structure(sensed: np.ndarray, fd_step: float, min_gap: float = 100.0,
                    noise_sd: float | None = None, noise_gap: float = 4.0,
                    spent: float = 0.0):
    """``(BodyStructure, settled)`` of probe rows ``(B, 1 + 4M, R, S)``
    (``probe_rows``, repeats averaged over the finite ones). ``settled``
    always without ``noise_sd`` or with one repeat; else unless the floor
    of the budget, of which ``spent`` is spent, would count more
    (``more_could_count``, the Jacobians' noise shown by half the
    difference of the even and the odd repeats' Jacobians). With repeats,
    the structure carries the receptors' part of their spread
    (``receptor_noise``)."""
    n_states, n_motors = sensed.shape[0], (sensed.shape[1] - 1) // 4
    repeats = sensed.shape[2]
    jac, floor = jacobians_and_floor(sensed, n_states, n_motors, fd_step, repeats, noise_sd)
    singular = np.linalg.svd(jac, compute_uv=False)
    structure = structure_from_probes(singular, floor, n_motors, min_gap,
                                      None if noise_sd is None else noise_gap)
    if noise_sd is None or repeats < 2:
        return structure, True
    structure = replace(structure, receptor_noise=across_range_sd(
        sensed[:, 0], jac, structure.pose_rank))
    halves = [jacobians_and_floor(sensed[:, :, part::2], n_states, n_motors, fd_step,
                                  len(range(part, repeats, 2)), noise_sd)[0] for part in (0, 1)]
    noise = 0.5 * (halves[0] - halves[1])
    ranks = noise_rank(singular, floor, noise_gap)[0]
    return structure, not more_could_count(jac, noise, floor, ranks, structure.pose_rank,
                                           noise_gap, spent)


def more_could_count(jac, noise, floor, ranks: np.ndarray, rank: int, gap: float,
                     spent: float) -> bool:
    """Whether the budget's floor would count more of the Jacobians ``jac``
    than the vote for ``rank`` did (``residual_could_count``, arguments as
    there): beyond ``rank`` at every probe, or the ``rank``-th direction at
    the probes that counted one less (``ranks``, each probe's count)."""
    lagging = np.asarray(ranks) == rank - 1
    if residual_could_count(jac, noise, floor, rank, gap, spent):
        return True
    return bool(rank > 0 and lagging.any() and residual_could_count(
        jac[lagging], None if noise is None else noise[lagging], np.asarray(floor)[lagging],
        rank - 1, gap, spent))


def repeat_variance(sensed: np.ndarray) -> float:
    """Variance of one sensing about the mean of its row's repeats, pooled
    over the rows, receptors and repeats of ``sensed`` ``(..., R, S)``
    (finite rows only; 0 where no row has two): the random part of the
    noise as the probes themselves show it."""
    values = np.where(np.isfinite(sensed), sensed, np.nan)
    count = np.sum(np.isfinite(values), axis=-2, keepdims=True)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(values, axis=-2, keepdims=True)
    dof = float(np.sum(np.maximum(count - 1, 0)))
    return float(np.nansum((values - mean) ** 2) / dof) if dof > 0 else 0.0


# Standard deviations of the residual's excess over its noise added to it,
# for an upper bound of the uncounted directions' strength.
_RESIDUAL_SDS = 2.0


def residual_could_count(jac: np.ndarray, noise: np.ndarray | None, floor: np.ndarray,
                         rank: int, gap: float, spent: float) -> bool:
    """Whether the Jacobians ``jac`` ``(B, S, M)`` hold, beyond their
    ``rank`` strongest directions and pooled over the probes, a direction
    that the floor of the averaging budget would count at ``gap`` floors:
    ``spent`` is the share of the budget spent (repeats or cloud pairs),
    and the noise's floor falls as its square root, to ``floor *
    sqrt(spent)``.

    Where a Jacobian has rank ``r``, the squares of its trailing singular
    values sum, to first order, to the squared norm of its noise's block
    outside its ``r`` leading left and right singular vectors. ``noise``
    ``(B, S, M)`` is a draw of the Jacobians' own noise (half the
    difference of two independent halves' Jacobians): that block of it sums
    to as much, give or take a chi-square's spread. The noise's shape is so
    measured, not assumed (a joint landing off its command errs along the
    Jacobian's range, receptor noise in every direction); with ``noise``
    None every entry errs alike and independently, with the sd ``floor``
    stands for (``floor / (sqrt(S) + sqrt(M))``). Whatever the trailing
    values add beyond the noise is an uncounted direction (a pose direction
    fainter than the floor, or the differences' truncation); its strength,
    bounded above with ``_RESIDUAL_SDS`` of that spread, is compared with
    what the budget's floor would count. Probes with a lost row (floor 1,
    ``jacobians_and_floor``) are left out."""
    n_sensors, n_motors = jac.shape[1:]
    rank = int(rank)
    kept = np.asarray(floor) != 1.0
    if noise is not None:
        kept &= np.all(np.isfinite(noise), axis=(1, 2))
    if rank >= n_motors or not kept.any():
        return False
    left, singular, right = np.linalg.svd(jac[kept])
    signal = float(np.sum(singular[:, rank:] ** 2))
    dof = int(kept.sum()) * (n_sensors - rank) * (n_motors - rank)
    if noise is None:
        entry = np.asarray(floor, dtype=float)[kept] / (np.sqrt(n_sensors) + np.sqrt(n_motors))
        expected = float(np.sum(entry ** 2)) * (n_sensors - rank) * (n_motors - rank)
    else:
        block = np.einsum("bsi,bsm,bjm->bij", left[:, :, rank:], noise[kept],
                          right[:, rank:, :])
        expected = float(np.sum(block ** 2))
    bound = signal - expected + _RESIDUAL_SDS * 2.0 * expected / np.sqrt(dof)
    counted = gap * np.asarray(floor, dtype=float)[kept] * np.sqrt(spent)
    return bound >= float(np.sum(counted ** 2))


def measure_cloud_structure(body, center: np.ndarray, *, step, probes: int = 8,
                            radius: float = 0.1, rank_gap: float = 2.0,
                            spent: float | None = None):
    """Pose rank, POV dimension and gain of ``body`` around ``center`` from
    Jacobians fitted over clouds of states (``step``, a
    ``jacobians.CloudStep``) at ``probes`` states, in ONE ``sense`` call of
    ``probes * (1 + 2 * step.pairs)`` rows: the measure where the outputs
    are rounded (sensing one state again repeats its error exactly).

    Each probe's Jacobian is the slope of a cubic fitted to its cloud: on
    the symmetric cloud the quadratic terms leave the slope alone and the
    cubic ones are fitted, so what the step's curvature still adds is of
    fifth order (a quadratic's slope keeps the third-order part, which on
    rendered images lifts a POV's tangent above the floor). Its floor is
    the spectral norm its error would have if every entry erred
    independently, ``s (sqrt(S) + sqrt(M))``, ``s`` the sd of a fitted slope
    for the misfit the cloud itself shows. A singular value counts when it
    is at least ``rank_gap`` floors.

    With ``spent`` (the share of the budget of pairs these clouds are),
    returns ``(BodyStructure, settled)``: settled unless the budget's
    clouds would count more
    (``more_could_count``, the fit's errors taken independent, of the sd
    its floor stands for)."""
    center = np.asarray(center, dtype=float).reshape(-1)
    n_motors = len(center)
    states = probe_states(center, int(probes), radius)
    sensed = np.asarray(body.sense(jacobian_stencil(states, step)), dtype=float)
    answer = sensed.reshape(len(states), stencil_rows(n_motors, step), -1)
    finite = np.all(np.isfinite(answer), axis=(1, 2))
    answer = np.where(np.isfinite(answer), answer, 0.0)
    _, jac, misfit = cloud_fit(answer, step, degree=3)
    _, _, slope_sd = cloud_design(n_motors, step.pairs, 3)
    spread = np.sqrt(answer.shape[-1]) + np.sqrt(n_motors)
    floor = misfit * float(np.max(slope_sd)) / float(step) * spread
    # A probe with a lost row does not vote (J = 0 against a floor of 1).
    jac[~finite], floor = 0.0, np.where(finite, floor, 1.0)
    singular = np.linalg.svd(jac, compute_uv=False)
    floor = np.maximum(floor, 1e-300)
    structure = structure_from_probes(singular, floor, n_motors, rank_gap, rank_gap)
    if spent is None:
        return structure
    ranks = noise_rank(singular, floor, rank_gap)[0]
    return structure, not more_could_count(jac, None, floor, ranks, structure.pose_rank,
                                           rank_gap, spent)


# Cloud half widths tried, as shares of ``naive.cloud_step``.
_CLOUD_LADDER = (1.0, 0.5, 0.25)


def rounded_structure(body, center: np.ndarray, params) -> BodyStructure:
    """The structure of a body whose outputs are rounded, from Jacobians
    fitted over clouds of ``2 * cloud_pairs`` states around each probe
    (``structure.measure_cloud_structure``). A wider cloud averages the
    rounding over more steps (its floor falls as 1 / width) while the
    polynomial follows the sensation less well (its misfit grows with the
    width): the widths of ``_CLOUD_LADDER`` are measured and the one of the
    lowest floor (relative to the gain) is kept; its clouds are then made
    four times larger, up to ``cloud_max_pairs`` (a budget), while that
    reveals more of the rank, the probes disagree, or the clouds of the
    budget would count more than the rank (``structure.more_could_count``,
    the fit's errors taken independent, of the sd its floor stands for;
    where the floor overstates them, as on the MuJoCo body's images, whose
    trailing singular values sum to less than it predicts, the first
    reasons are left)."""
    pairs = int(params.cloud_pairs)

    def measured(width, pairs):
        with getattr(body, "fresh", contextlib.nullcontext)():
            return measure_cloud_structure(
                body, center, step=CloudStep(width, pairs, len(center)),
                probes=params.structure_probes, radius=params.structure_radius,
                rank_gap=params.cloud_rank_gap, spent=pairs / params.cloud_max_pairs)

    tried = [(params.cloud_step * share, measured(params.cloud_step * share, pairs))
             for share in _CLOUD_LADDER]
    width, (structure, settled) = min(
        tried, key=lambda t: t[1][0].floor / max(t[1][0].gain, 1e-300))
    revealed = -1
    while 4 * pairs <= params.cloud_max_pairs and not (
            settled and structure.votes == structure.probes and structure.pose_rank <= revealed):
        revealed, pairs = structure.pose_rank, 4 * pairs
        structure, settled = measured(width, pairs)
    return structure
