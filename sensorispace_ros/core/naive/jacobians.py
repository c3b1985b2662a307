"""Sensory Jacobians by finite differences through ``sense``, their rank
test and the minimum-norm Gauss-Newton step: what every naive sampler and
search builds on. Motor states are phases (``sense_memory.MotorPhase``); the
rank is the body's pose rank as the agent measured it
(``structure.measure_structure``), never a constant.
"""
from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

# Outcomes of a POV sampler (``SensoryPointsOfView.reason``).
VALID = "ok"
SPLIT = "split"                 # the loop came back to its start only a period away
NOT_CLOSED = "not_closed"       # budget spent before the walk closed or covered its POV
RANK_DEFICIENT = "rank_deficient"  # the sensation does not pin the sensor's configuration
UNSUPPORTED = "unsupported"     # a POV dimension no sampler here covers



@dataclass
class SensoryPointsOfView:
    """POVs sampled through the body, one row per starting motor state.

    ``samples[p]`` ``(n_samples, M)``: unwrapped motor states spread evenly
    over the POV (equally spaced in arc length along a loop),
    ``samples[p, 0]`` the start. ``valid[p]`` False when the sampler could
    not sample the whole POV (``reason[p]``: ``"split"``, ``"not_closed"``,
    ``"rank_deficient"``, ``"unsupported"``). ``queries[p]``: motor states
    probed for POV ``p``; ``calls``: ``sense`` calls of the whole batch.
    ``steps[p]``: knots of the walk (corrected predictions kept, both
    fronts); ``max_residual``: largest
    sensory error ``|sense(sample) - sense(start)|`` of a valid POV's final
    samples; ``target_sensations[p]`` the start's sensation.
    """

    samples: np.ndarray
    valid: np.ndarray
    reason: list
    queries: np.ndarray
    steps: np.ndarray
    calls: int
    max_residual: float
    target_sensations: np.ndarray


class SymmetricStep(float):
    """A finite-difference step (phase) whose Jacobians are central
    differences: each state is sensed with ``+-step`` along every joint
    (``2M + 1`` rows instead of ``M + 1``). Its truncation error is second
    order in the step and its noise half a forward difference's at one
    step, so under sensory noise a larger step gives a Jacobian whose weak
    directions stand out of the noise (``noise.sized_params`` chooses it);
    everywhere else it is the float it equals."""

    __slots__ = ()

    def __reduce__(self):
        return (SymmetricStep, (float(self),))


class AveragedStep(SymmetricStep):
    """A ``SymmetricStep`` whose every stencil row is sensed ``repeats``
    times and averaged: ``repeats * (2M + 1)`` rows per state, the noise of
    the Jacobian and of the state's sensation over ``sqrt(repeats)``. Where
    the pose's weakest direction lies below one symmetric difference's noise
    no rank test could pass it (``noise.finite_difference_step`` chooses
    it). The repeats of a row lie ``REPEAT_JITTER`` phase apart (``r * REPEAT_JITTER``
    along the first joint), so that every row is a motor state of its own
    and no repeat is answered from what was sensed before instead of sensed.
    Everywhere else it is the float it equals."""

    def __new__(cls, step: float, repeats: int):
        if int(repeats) != repeats or repeats < 1:
            raise ValueError(f"repeats must be an integer >= 1, got {repeats}")
        value = super().__new__(cls, step)
        value.repeats = int(repeats)
        return value

    def __reduce__(self):
        return (AveragedStep, (float(self), self.repeats))

    def __repr__(self):
        return f"AveragedStep({float(self)!r}, repeats={self.repeats})"


# Distance (phase) between two repeats of one stencil row of an ``AveragedStep``:
# far below any step, far above float64 round-off of a phase.
REPEAT_JITTER = 1e-12


def halved(fd_step: float) -> float:
    """The step of the same kind (and repeats) at half its size."""
    if isinstance(fd_step, AveragedStep):
        return AveragedStep(float(fd_step) / 2.0, fd_step.repeats)
    if isinstance(fd_step, SymmetricStep):
        return SymmetricStep(float(fd_step) / 2.0)
    return float(fd_step) / 2.0


class CloudStep(float):
    """A finite-difference "step" (phase) whose Jacobians are fits: each
    state is sensed with ``2 * pairs`` states around it, in pairs ``+-x``
    over the cube of half width ``step`` (fixed Halton points), and a
    quadratic in the motor offsets is fitted to each receptor by least
    squares. The fit's slope is the Jacobian and its value at the state the
    sensation. Rounding to fixed steps repeats exactly, so sensing one state
    again tells nothing new; states a little apart round differently, and
    the fit averages their rounding errors (sd ``quantum / sqrt(12)`` each)
    over the ``2 * pairs`` rows, which repeats cannot. The quadratic terms
    take up the curvature; the symmetric design keeps odd terms out of the
    value (the rank probes fit a cubic, ``structure.measure_cloud_structure``).
    Everywhere else it is the float it equals."""

    def __new__(cls, step: float, pairs: int, n_motors: int):
        for name, value in (("pairs", pairs), ("n_motors", n_motors)):
            if int(value) != value or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value}")
        value = super().__new__(cls, step)
        value.pairs, value.n_motors = int(pairs), int(n_motors)
        return value

    def __reduce__(self):
        return (CloudStep, (float(self), self.pairs, self.n_motors))

    def __repr__(self):
        return f"CloudStep({float(self)!r}, pairs={self.pairs}, n_motors={self.n_motors})"


# A design of 2 x 16,384 pairs and its fit take ~10 MB: a few are kept.
@functools.lru_cache(maxsize=6)
def cloud_design(n_motors: int, pairs: int, degree: int = 2):
    """``(offsets (1 + 2 pairs, M), fit (P, 1 + 2 pairs), slope_sd (M,))`` of
    a ``CloudStep`` in units of its step: the state, ``pairs`` Halton points
    of ``[-1, 1]^M``, their mirror images; the least-squares operator of the
    polynomial model of ``degree`` (value, M slopes, higher terms); the
    factor from a row's error sd to each fitted slope's sd."""
    points = 2.0 * qmc.Halton(d=int(n_motors), scramble=False).random(int(pairs) + 1)[1:] - 1.0
    offsets = np.vstack([np.zeros((1, n_motors)), points, -points])
    fit = np.linalg.pinv(polynomial_model(offsets, degree))
    return offsets, fit, np.sqrt(np.sum(fit[1:1 + n_motors] ** 2, axis=1))


def polynomial_model(offsets: np.ndarray, degree: int = 2) -> np.ndarray:
    """Columns 1, ``x_i``, then the products of 2 .. ``degree`` offsets
    (each set of indices once) of offsets ``(K, M)``."""
    n_motors = offsets.shape[1]
    columns = [np.ones((len(offsets), 1)), offsets]
    for order in range(2, int(degree) + 1):
        for index in itertools.combinations_with_replacement(range(n_motors), order):
            columns.append(np.prod(offsets[:, index], axis=1)[:, None])
    return np.hstack(columns)


def cloud_fit(answer: np.ndarray, fd_step: "CloudStep", degree: int = 2):
    """``(sensations (..., S), jacobians (..., S, M), misfit sd (...))`` of a
    ``CloudStep``'s rows ``answer`` ``(..., rows, S)`` fitted by the
    polynomial of ``degree``; the misfit sd is the root mean square
    residual over receptors and the fit's degrees of freedom (the error sd
    of one sensed value, or more where the polynomial does not follow)."""
    offsets, fit, _ = cloud_design(fd_step.n_motors, fd_step.pairs, degree)
    coef = np.einsum("pk,...ks->...ps", fit, answer)
    model = polynomial_model(offsets, degree)
    residual = answer - np.einsum("kp,...ps->...ks", model, coef)
    dof = max(len(offsets) - model.shape[1], 1)
    misfit = np.sqrt(np.sum(residual ** 2, axis=(-2, -1)) / (dof * answer.shape[-1]))
    jac = np.swapaxes(coef[..., 1:1 + fd_step.n_motors, :], -1, -2) / float(fd_step)
    return coef[..., 0, :].copy(), jac, misfit


def stencil_rows(n_motors: int, fd_step: float) -> int:
    """Rows ``jacobian_stencil`` senses per state."""
    if isinstance(fd_step, CloudStep):
        return 1 + 2 * fd_step.pairs
    if isinstance(fd_step, AveragedStep):
        return (2 * int(n_motors) + 1) * fd_step.repeats
    return (2 if isinstance(fd_step, SymmetricStep) else 1) * int(n_motors) + 1


def sensory_jacobian(body, motor_states: np.ndarray, fd_step: float = 1e-6,
                     sensed: np.ndarray | None = None):
    """Sensations and finite-difference sensory Jacobians of many motor states
    in ONE ``sense`` call.

    ``motor_states`` ``(B, M)``. Returns ``(sensations (B, S), jacobians
    (B, S, M), rows)`` where ``rows = B * stencil_rows(M, fd_step)`` is the
    number of motor states probed. Rows are ordered state by state (the
    state, then its displaced copies), so the arm ends at the last state's
    stencil. A state with a lost (non-finite) row gets a NaN sensation and
    a zero Jacobian. ``sensed`` ``(B, S)``: what the states themselves were
    just sensed giving, in this world; the stencil's first rows are then
    not sensed again (``B`` rows fewer). Only for a step whose stencil senses
    each state once (not ``AveragedStep`` or ``CloudStep``).
    """
    motor_states = np.asarray(motor_states, dtype=float)
    n_batch, n_motors = motor_states.shape
    rows = stencil_rows(n_motors, fd_step)
    stencil = jacobian_stencil(motor_states, fd_step)
    if sensed is None:
        answer = np.asarray(body.sense(stencil), dtype=float).reshape(n_batch, rows, -1)
    else:
        if isinstance(fd_step, (AveragedStep, CloudStep)):
            raise ValueError("sensed: the stencil of an averaged or cloud step senses each "
                             "state more than once")
        displaced = stencil.reshape(n_batch, rows, n_motors)[:, 1:].reshape(-1, n_motors)
        answer = np.asarray(body.sense(displaced), dtype=float).reshape(n_batch, rows - 1, -1)
        answer = np.concatenate([np.asarray(sensed, dtype=float)[:, None, :], answer], axis=1)
    sensations, jacobians = stencil_jacobian(answer, fd_step)
    # A state with a lost row (non-finite) has no Jacobian and no sensation:
    # J = 0 fails every rank test, a NaN sensation every comparison.
    lost = ~np.all(np.isfinite(answer), axis=(1, 2))
    sensations[lost] = np.nan
    jacobians[lost] = 0.0
    return sensations, jacobians, n_batch * (rows if sensed is None else rows - 1)


def stencil_jacobian(answer: np.ndarray, fd_step: float):
    """``(sensations (..., S), jacobians (..., S, M))`` from what the rows of
    ``jacobian_stencil`` sensed, ``answer`` ``(..., stencil_rows, S)``."""
    if isinstance(fd_step, CloudStep):
        sensations, jacobians, _ = cloud_fit(answer, fd_step)
        return sensations, jacobians
    answer = _repeats_averaged(answer, fd_step)
    sensations = answer[..., 0, :].copy()
    if isinstance(fd_step, SymmetricStep):
        _, ahead, behind = _central_sides(answer)
        return sensations, np.swapaxes(ahead - behind, -1, -2) / (2.0 * fd_step)
    return sensations, np.swapaxes(answer[..., 1:, :] - sensations[..., None, :], -1, -2) / fd_step


def stencil_bend(answer: np.ndarray, fd_step: float) -> np.ndarray:
    """``(...)``: how far the two one-sided differences of a central stencil
    disagree, over their sum (``|ahead + behind - 2 centre| / |ahead -
    behind|``, every joint and output at once) from what its rows
    ``answer`` ``(..., stencil_rows, S)`` sensed: near 0 where the sensation
    runs straight across the stencil, 1 where one side does not change at all
    (a jump within the step, whose secant is no slope of the state's pose).
    Zeros for a step without a side behind (forward or a cloud)."""
    if not isinstance(fd_step, SymmetricStep):
        return np.zeros(answer.shape[:-2])
    centre, ahead, behind = _central_sides(_repeats_averaged(answer, fd_step))
    axes = (-2, -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.linalg.norm(ahead + behind - 2.0 * centre, axis=axes) / \
            np.linalg.norm(ahead - behind, axis=axes)


def _repeats_averaged(answer: np.ndarray, fd_step: float) -> np.ndarray:
    """``answer`` with the repeats of each row of an ``AveragedStep`` averaged."""
    if not isinstance(fd_step, AveragedStep):
        return answer
    answer = answer.reshape(answer.shape[:-2] + (-1, fd_step.repeats, answer.shape[-1]))
    return answer.mean(axis=-2)


def _central_sides(answer: np.ndarray):
    """``(centre (..., 1, S), ahead (..., M, S), behind (..., M, S))``: the rows
    of a central stencil ``answer`` ``(..., 2M + 1, S)``."""
    n_motors = (answer.shape[-2] - 1) // 2
    return answer[..., :1, :], answer[..., 1:n_motors + 1, :], answer[..., n_motors + 1:, :]


def jacobian_stencil(motor_states: np.ndarray, fd_step: float = 1e-6) -> np.ndarray:
    """The rows ``sensory_jacobian`` senses for ``motor_states`` ``(B, M)``:
    ``(B * stencil_rows, M)``, each state then its displaced copies (``+h``
    along each joint, then ``-h`` for a ``SymmetricStep``)."""
    motor_states = np.asarray(motor_states, dtype=float)
    n_batch, n_motors = motor_states.shape
    if isinstance(fd_step, CloudStep):
        offsets, _, _ = cloud_design(n_motors, fd_step.pairs)
        return (motor_states[:, None, :] + float(fd_step) * offsets[None]).reshape(-1, n_motors)
    repeats = fd_step.repeats if isinstance(fd_step, AveragedStep) else 1
    stencil = np.repeat(motor_states[:, None, :], stencil_rows(n_motors, fd_step) // repeats,
                        axis=1)
    stencil[:, 1:n_motors + 1, :] += fd_step * np.eye(n_motors)
    if isinstance(fd_step, SymmetricStep):
        stencil[:, n_motors + 1:, :] -= fd_step * np.eye(n_motors)
    if repeats > 1:
        stencil = np.repeat(stencil, repeats, axis=1)
        stencil[:, :, 0] += REPEAT_JITTER * np.tile(np.arange(repeats), stencil.shape[1] // repeats)
    return stencil.reshape(-1, n_motors)


def jacobian_svd(jacobians: np.ndarray):
    """SVD pieces of sensory Jacobians ``(B, S, M)``: singular values
    ``(B, min(S, M))`` and right singular vectors ``(B, M, M)`` (rows)."""
    _, singular, right = np.linalg.svd(jacobians)
    return singular, right


def has_full_pose_rank(jacobians: np.ndarray, rank: int, rank_ratio: float = 1e-3,
                       min_singular: float = 0.0, sensations: np.ndarray | None = None,
                       pattern_ratio: float = 1e-6) -> np.ndarray:
    """True where a sensory Jacobian ``(B, S, M)`` has the body's pose rank
    ``rank`` (``structure.measure_structure``): its ``rank``-th singular
    value is at least ``rank_ratio`` times the first and at least
    ``min_singular``. The sensation then pins the sensor's configuration
    locally; a blank (J = 0) or one-light sensation does not.

    With ``sensations`` ``(B, S)`` (the sensations there) the
    ``gain_free_jacobian`` must pass the ratio test too, at ``pattern_ratio``:
    a sensation must pin the configuration by its pattern, not only by its
    overall gain. A pattern that cannot vary in ``rank`` directions has a
    ratio at the finite-difference noise (~1e-10 here); patterns that can,
    1e-4 and more."""
    jacobians = np.asarray(jacobians, dtype=float)
    full = _rank_test(jacobians, rank, rank_ratio, min_singular)
    if sensations is not None:
        full &= _rank_test(gain_free_jacobian(jacobians, sensations), rank, pattern_ratio, 0.0)
    return full


def gain_free_jacobian(jacobians: np.ndarray, sensations: np.ndarray) -> np.ndarray:
    """``d(s / |s|) / dm = (I - u u^T) J / |s|`` with ``u = s / |s|``: how the
    sensation's direction changes, without the change of its overall gain.

    A sensation seen from one light source of a set of alike ones (a light
    among identical lights) pins where that source is, not which source it
    is: its overall gain and its pattern both depend on the one source, and
    another source seen from the same relative place gives the very same
    sensation. Its pattern alone varies in fewer directions than the pose
    rank; a sensation of several sources varies in more."""
    sensations = np.asarray(sensations, dtype=float)
    norm = np.linalg.norm(sensations, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.where(norm[:, None] > 0, sensations / norm[:, None], 0.0)
        along = np.einsum("bs,bsm->bm", unit, jacobians)
        projected = jacobians - unit[:, :, None] * along[:, None, :]
        return np.where(norm[:, None, None] > 0, projected / norm[:, None, None], 0.0)


def _rank_test(jacobians, rank, rank_ratio, min_singular):
    singular = np.linalg.svd(jacobians, compute_uv=False)
    if rank < 1 or rank > singular.shape[1]:
        return np.zeros(len(singular), dtype=bool)
    weakest = singular[:, rank - 1]
    return (weakest >= rank_ratio * singular[:, 0]) & (weakest >= min_singular) & (weakest > 0.0)


def minimum_norm_correction(jacobians: np.ndarray, residuals: np.ndarray,
                            rank: int) -> np.ndarray:
    """Gauss-Newton step ``-J_r^+ r`` with ``J`` truncated to its ``rank``
    largest singular values: the correction moves across the level set,
    never along it (the discarded directions are the POV's tangents)."""
    u, singular, right = np.linalg.svd(jacobians, full_matrices=False)
    # A blank sensation has J = 0 (or a singular value of ~1e-300): its
    # "correction" is infinite, never small.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        coeff = np.einsum("bsk,bs->bk", u[:, :, :rank], residuals) / singular[:, :rank]
        return -np.einsum("bk,bkm->bm", coeff, right[:, :rank, :])


def repair_rows(body, flat: np.ndarray, target: np.ndarray, rows: np.ndarray, *, rank: int,
                fd_step: float, tol: float, rounds: int = 3):
    """Gauss-Newton steps with fresh Jacobians (one ``sense`` call each) on
    the ``rows`` of ``flat`` (in place) until each row's step is within
    ``tol`` (phase). Returns ``(calls, rows sensed per repaired row (list,
    one per call, of the rows then sensed), the rows that never got
    there)``; a row whose sensation was lost keeps its state and never gets there."""
    calls, sensed, lost = 0, [], []
    for _ in range(rounds):
        if not len(rows):
            break
        sensation, jac, _ = sensory_jacobian(body, flat[rows], fd_step)
        calls += 1
        sensed.append(rows.copy())
        step = minimum_norm_correction(jac, sensation - target[rows], rank)
        finite = np.isfinite(step).all(axis=1)      # a lost row: no step, not repaired
        lost.append(rows[~finite])
        rows, step = rows[finite], step[finite]
        flat[rows] += step
        rows = rows[~(np.linalg.norm(step, axis=1) <= tol)]
    return calls, sensed, np.concatenate([rows, *lost]).astype(int)


# Standard deviations of its noise the component of a residual along one of
# the Jacobian's directions must exceed before a walk corrects it in full
# (``shrink``): below, it is mostly the noise of one sensing.
_SHRINK_SDS = 2.0


def shrink(along: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Positive-part shrinkage ``max(0, 1 - (z sd / a)^2)`` of components
    ``along`` ``(B, k)`` whose noise sd is ``noise`` ``(B,)`` (``z`` is
    ``_SHRINK_SDS``): a component well above its noise is kept, one at the
    noise mostly dropped, so a walk does not chase one sensing's noise along
    a faint pose direction."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        factor = 1.0 - (_SHRINK_SDS * noise[:, None]) ** 2 / along ** 2
    return np.clip(np.nan_to_num(factor, nan=0.0, neginf=0.0), 0.0, 1.0)


def loop_smoothed_correction(jacobians: np.ndarray, residuals: np.ndarray, rank: int,
                             noise: float, per_loop: int) -> np.ndarray:
    """Gauss-Newton steps of the samples of loops (rows in blocks of
    ``per_loop`` samples along each loop), each of whose components along
    the Jacobian's ``rank`` directions is filtered along its loop: every
    sample of a POV lies on one level set, so its offsets from it vary
    smoothly along the loop, while one sensing's noise (sd ``noise`` per
    residual component) does not. A Fourier mode of a component is kept
    (whole: no bias) where its power stands out of what the noise gives
    any of the modes, else dropped: a strong direction keeps the modes of
    its offsets, a faint one its slow offsets only. Non-finite rows (lost
    sensings) count as 0."""
    u, singular, right = np.linalg.svd(jacobians, full_matrices=False)
    u, right, singular = u[:, :, :rank], right[:, :rank, :], singular[:, :rank]
    blocks = len(jacobians) // per_loop
    u = u.reshape(blocks, per_loop, -1, rank)
    # SVD vectors have arbitrary signs: flip each sample's pair (u, v) to
    # follow the previous sample's along the loop.
    flips = np.sign(np.einsum("lisk,lisk->lik", u[:, 1:], u[:, :-1]))
    flips[flips == 0] = 1.0
    sign = np.concatenate([np.ones((blocks, 1, rank)), np.cumprod(flips, axis=1)], axis=1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        coeff = (np.einsum("lisk,lis->lik", u, residuals.reshape(blocks, per_loop, -1))
                 * sign / singular.reshape(blocks, per_loop, rank))
        variance = (noise / singular.reshape(blocks, per_loop, rank)) ** 2
    lost = ~np.isfinite(coeff) | ~np.isfinite(variance)
    coeff, variance = np.where(lost, 0.0, coeff), np.where(lost, 0.0, variance)
    modes = np.fft.rfft(coeff, axis=1)
    power = np.abs(modes) ** 2
    # The universal threshold: the largest of n noise modes' powers stays below
    # 2 ln(n) times their mean (the noise's summed variance).
    kept = power > 2.0 * np.log(power.shape[1]) * np.sum(variance, axis=1, keepdims=True)
    smooth = np.fft.irfft(np.where(kept, modes, 0.0), n=per_loop, axis=1) * sign
    return -np.einsum("bk,bkm->bm", smooth.reshape(-1, rank), right)
