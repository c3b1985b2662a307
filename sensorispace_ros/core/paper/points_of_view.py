"""Points of view (POVs): the motor states that share one sensor pose
(paper Sec. 3.1, "Estimating the agent's points of view").

A POV is the fibre f^-1(f(m)) of the forward model. On the paper arm
(f: R^4 -> R^3) it is a closed 1-D loop in the motor torus, represented by
``N`` motor states spread evenly along it. Motor angles stay *unwrapped*
(continuous along the loop); compare them with the periodic motor metric.

Any body (``core.arm.Arm``) by the dimension of its fibres: 1 walks the
Jacobian kernel (the paper arm by its closed-form step, others by
``chain_walk``); 0 keeps the motor state and the pose's other solutions
(``fibres.discrete_fibre``), repeated to ``N`` rows; 2 samples the surface
evenly (``surfaces``). Other motor units are sampled in radians and
converted back.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from sensorispace_ros.core import arm
from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.paper import chain_walk
from sensorispace_ros.core.paper.fibres import discrete_fibre
from sensorispace_ros.core.paper.surfaces import sample_surface
from sensorispace_ros.core.motor_loops import loop_winding  # noqa: F401  (re-exported: part of this API)

TWO_PI = 2.0 * np.pi
N_SAMPLES_2D = 1600


def resample_closed_path(path: np.ndarray, n_samples: int = 100) -> np.ndarray:
    """``n_samples`` points equally spaced in arc length along a closed loop.

    ``path`` ``(n, J)`` is unwrapped, starts at the POV's first motor state and
    ends near it modulo 2 pi per joint. The loop is closed by appending the
    start shifted by the per-joint multiple of 2 pi that makes the closing
    segment short (``loop_winding``). Arc length is Euclidean in unwrapped
    coordinates; the first sample is ``path[0]``. Angles are returned as given
    (not wrapped), shape ``(n_samples, J)``.
    """
    path = _as_path(path)
    if int(n_samples) != n_samples or n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer, got {n_samples}")
    n_samples = int(n_samples)
    closing = path[0] + TWO_PI * loop_winding(path)
    loop = np.vstack([path, closing[None, :]])
    segment = np.linalg.norm(np.diff(loop, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(segment)])
    if arc[-1] <= 0.0:
        raise ValueError("path has zero length: cannot resample a loop")
    # Equal spacing over the whole closed length; the end (== start mod 2 pi)
    # is excluded so no sample repeats.
    targets = np.arange(n_samples) * (arc[-1] / n_samples)
    return np.stack([np.interp(targets, arc, loop[:, j]) for j in range(loop.shape[1])],
                    axis=-1)


def _as_path(path: np.ndarray) -> np.ndarray:
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) < 2:
        raise ValueError(f"path must have shape (n >= 2, joints), got {path.shape}")
    if not np.all(np.isfinite(path)):
        raise ValueError("path contains non-finite values")
    return path


# --------------------------------------------------------------------------
# Paper strategy: walk the kernel of the arm's Jacobian (analytic).
# --------------------------------------------------------------------------

VALID = "ok"
SPLIT = "split"
NOT_CLOSED = "not_closed"


@dataclass
class PointsOfViewResult:
    """Sampled points of view, one row per starting motor state.

    ``samples[p]`` holds ``n_samples`` unwrapped motor states of POV ``p``,
    the first being the starting state; ``valid[p]`` is False for POVs the
    walk cannot sample whole (``reason[p]`` says why: ``"split"`` when the
    fibre is two disjoint loops, paper Fig. 5b; ``"not_closed"`` when the walk
    did not come back within ``max_steps``). ``steps[p]`` counts kernel steps
    until the loop closed (0-D and 2-D POVs, which are not walked: their
    distinct samples); ``max_pose_drift`` is the largest pose error of any
    sample with respect to its POV's starting pose. Samples are in the arm's
    motor unit.
    """

    samples: np.ndarray
    valid: np.ndarray
    reason: list
    steps: np.ndarray
    max_pose_drift: float
    winding: np.ndarray = field(repr=False, default=None)


def sample_points_of_view(motor_states: np.ndarray, *, step: float = 1e-3,
                          n_samples: int = 100, min_steps: int = 50,
                          close_tol: float = 1e-2, max_steps: int = 200_000,
                          newton_tol: float = 1e-12, record_every: int = 5,
                          progress=None, body_arm: Arm = PAPER_ARM,
                          n_samples_2d: int = N_SAMPLES_2D) -> PointsOfViewResult:
    """Sample the POV of every motor state of ``body_arm`` (the paper arm by
    default) by walking the Jacobian kernel (paper Sec. 4.1, "Estimating the
    agent's points of view"), or, for fibres of dimension 0 and 2, as the
    module docstring says (``n_samples_2d`` samples on a surface).

    From ``m_i`` the walk repeats ``m <- m + gamma * step * k / |k|`` with
    ``k`` the kernel of ``J_f(m)`` (signed maximal minors) and ``gamma = +-1``
    keeping the direction, until at least ``min_steps`` steps were taken and
    the periodic motor distance to ``m_i`` is below ``close_tol`` (paper:
    eps = 1e-3, 50 steps, 1e-2; radians). All POVs walk together as one
    ``(P, J)`` batch. The loop is then resampled at ``n_samples`` points
    equally spaced in arc length, each projected back onto ``f(m) = f(m_i)``.

    ``record_every``: the walk path is kept every that many steps (plus the
    closing state) to bound memory (hundreds of loops of ~10^4 steps); the chords
    between records leave the manifold by O((record_every * step)^2 *
    curvature), which the final projection removes.
    ``progress(done, total)`` is called as POVs close.
    """
    if body_arm.unit != "rad":
        return _in_motor_unit(motor_states, body_arm, step=step, n_samples=n_samples,
                              min_steps=min_steps, close_tol=close_tol, max_steps=max_steps,
                              newton_tol=newton_tol, record_every=record_every,
                              progress=progress, n_samples_2d=n_samples_2d)
    start = np.array(motor_states, dtype=float, copy=True)
    _check_walk(start, step=step, n_samples=n_samples, min_steps=min_steps,
                close_tol=close_tol, max_steps=max_steps, record_every=record_every,
                joints=body_arm.n_joints)
    if body_arm.pov_dim != 1:
        return _sampled_fibres(start, body_arm, n_samples=n_samples, n_samples_2d=n_samples_2d,
                               newton_tol=newton_tol, progress=progress)
    target = body_arm.forward(start)
    kernel_step = _corrected_kernel_step if body_arm.is_paper else chain_walk.kernel_step(body_arm)
    walk = _walk_kernels(start, target, step=step, min_steps=min_steps, close_tol=close_tol,
                         max_steps=max_steps, record_every=record_every, progress=progress,
                         kernel_step=kernel_step)
    samples, winding, reason = _resample_walks(walk, n_samples, record_every)
    samples, drift = project_onto_pose(samples, target, tol=newton_tol, body_arm=body_arm)
    return PointsOfViewResult(samples=samples, valid=np.array([r == VALID for r in reason]),
                              reason=reason, steps=walk.steps,
                              max_pose_drift=float(drift.max()) if drift.size else 0.0,
                              winding=winding)


def _in_motor_unit(motor_states, body_arm: Arm, **options) -> PointsOfViewResult:
    """``sample_points_of_view`` of an arm in another unit than radians: the
    same arm in radians samples, the samples are converted back (the first
    of each is its motor state as given)."""
    motor_states = np.asarray(motor_states, dtype=float)
    radian_arm = Arm(body_arm.segments, body_arm.eye, "rad")
    sampled = sample_points_of_view(body_arm.to_radians(motor_states), body_arm=radian_arm,
                                    **options)
    samples = body_arm.from_radians(sampled.samples)
    samples[:, 0] = motor_states
    return replace(sampled, samples=samples)


def _sampled_fibres(start, body_arm: Arm, *, n_samples, n_samples_2d, newton_tol, progress):
    """POVs of dimension 0 (every solution of the pose, each repeated in a
    block of rows, ``n_samples`` in all) or 2 (``n_samples_2d`` samples of the
    surface); all valid, ``steps`` counts the distinct samples."""
    dim = body_arm.pov_dim
    if dim not in (0, 2):
        raise ValueError(f"points of view of dimension {dim} are not sampled "
                         f"(0, 1 and 2 are): {body_arm}")
    rows = int(n_samples) if dim == 0 else int(n_samples_2d)
    if rows < 1:
        raise ValueError(f"n_samples_2d must be a positive integer, got {n_samples_2d}")
    samples = np.empty((len(start), rows, start.shape[1]))
    distinct = np.zeros(len(start), dtype=int)
    for p, motor in enumerate(start):
        found = (discrete_fibre(body_arm, motor) if dim == 0
                 else sample_surface(body_arm, motor, rows))
        samples[p] = found[np.arange(rows) * len(found) // rows]
        distinct[p] = len(np.unique(found, axis=0))
        if progress is not None and ((p + 1) % 50 == 0 or p + 1 == len(start)):
            progress(p + 1, len(start))
    samples, drift = project_onto_pose(samples, body_arm.forward(start), tol=newton_tol,
                                       body_arm=body_arm)
    samples[:, 0] = start
    return PointsOfViewResult(samples=samples, valid=np.ones(len(start), dtype=bool),
                              reason=[VALID] * len(start), steps=distinct,
                              max_pose_drift=float(drift.max()) if drift.size else 0.0,
                              winding=np.zeros(start.shape, dtype=int))


def _check_walk(start, *, step, n_samples, min_steps, close_tol, max_steps, record_every,
                joints=arm.N_JOINTS):
    if start.ndim != 2 or start.shape[1] != joints:
        raise ValueError(f"motor_states must have shape (P, {joints}), got {start.shape}")
    if not np.all(np.isfinite(start)):
        raise ValueError("motor_states contains non-finite values")
    if not step > 0:
        raise ValueError(f"step must be > 0, got {step}")
    if not close_tol > step:
        raise ValueError(f"close_tol must exceed step ({step}), got {close_tol}")
    for name, value in (("n_samples", n_samples), ("min_steps", min_steps),
                        ("max_steps", max_steps), ("record_every", record_every)):
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value}")
    if min_steps > max_steps:
        raise ValueError(f"min_steps ({min_steps}) must not exceed max_steps ({max_steps})")


@dataclass
class _KernelWalks:
    """What ``_walk_kernels`` found, per POV: ``steps`` until the loop closed
    (``max_steps`` if it did not), ``closed``, ``lap_end``/``lap_steps`` the
    first state back within ``close_tol`` and its step (0: never left the
    ball), ``final_state``; the walk's records as ``(POV, state)`` rows in
    walk order (``record_index``, ``record_state``)."""

    start: np.ndarray
    steps: np.ndarray
    closed: np.ndarray
    lap_end: np.ndarray
    lap_steps: np.ndarray
    final_state: np.ndarray
    record_index: np.ndarray
    record_state: np.ndarray


def _walk_kernels(start, target, *, step, min_steps, close_tol, max_steps, record_every,
                  progress, kernel_step=None) -> _KernelWalks:
    """Walk every POV's kernel from ``start`` until its loop closes (``min_steps``
    at least, back within ``close_tol``) or ``max_steps``; ``kernel_step(m, pose_target)``
    gives the corrected step and the unit kernel (default ``_corrected_kernel_step``)."""
    kernel_step = _corrected_kernel_step if kernel_step is None else kernel_step
    n_pov = len(start)
    steps = np.zeros(n_pov, dtype=int)
    closed = np.zeros(n_pov, dtype=bool)
    lap_end = np.zeros_like(start)                  # first state back within close_tol
    lap_steps = np.zeros(n_pov, dtype=int)
    final_state = start.copy()
    record_index = [np.arange(n_pov)]
    record_state = [start.copy()]

    # Working set of the POVs still walking, joint-major ``(J, n)`` (each step's
    # operations elementwise on contiguous rows); a POV leaves it when its loop closes.
    ids = np.arange(n_pov)
    m = start.T.copy()
    m_start = start.T.copy()
    pose_target = target.T.copy()
    _, direction = kernel_step(m, pose_target)
    left_start = np.zeros(n_pov, dtype=bool)        # went farther than close_tol once
    lapped = np.zeros(n_pov, dtype=bool)            # came back once (lap_end is set)
    for n in range(1, max_steps + 1):
        if len(ids) == 0:
            break
        # Paper Eq. (kernel walk): m <- m + gamma * eps * k / |k| ...
        m, new_direction = kernel_step(m + step * direction, pose_target)
        # ... with gamma = +-1 keeping the direction along the loop.
        backwards = np.einsum("ij,ij->j", new_direction, direction) < 0.0
        if backwards.any():
            new_direction[:, backwards] *= -1.0
        direction = new_direction

        away = _periodic_sq_distance(m, m_start) > close_tol ** 2
        left_start |= away
        first_back = left_start & ~away & ~lapped
        if np.any(first_back):
            lap_end[ids[first_back]] = m[:, first_back].T
            lap_steps[ids[first_back]] = n
            lapped |= first_back
        if n % record_every == 0:
            record_index.append(ids.copy())
            record_state.append(m.T.copy())
        done = ~away if n >= min_steps else None
        if done is not None and np.any(done):
            finished = ids[done]
            closed[finished] = True
            steps[finished] = n
            final_state[finished] = m[:, done].T
            keep = ~done
            ids, m, m_start, pose_target = ids[keep], m[:, keep], m_start[:, keep], pose_target[:, keep]
            direction, left_start, lapped = direction[:, keep], left_start[keep], lapped[keep]
            if progress is not None:
                progress(int(closed.sum()), n_pov)
    steps[ids] = max_steps
    final_state[ids] = m.T
    return _KernelWalks(start, steps, closed, lap_end, lap_steps, final_state,
                        np.concatenate(record_index), np.concatenate(record_state))


def _resample_walks(walk: _KernelWalks, n_samples, record_every):
    """Each POV's walked loop (its first lap) resampled at ``n_samples``
    points; returns ``(samples (P, n_samples, J), winding (P, J), reason)``."""
    n_pov, joints = walk.start.shape
    samples = np.empty((n_pov, int(n_samples), joints))
    winding = np.zeros((n_pov, joints), dtype=int)
    reason = []
    record_index = walk.record_index
    order = np.argsort(record_index, kind="stable")     # per POV, in walk order
    bounds = np.searchsorted(record_index[order], np.arange(n_pov + 1))
    record_state = walk.record_state[order]
    for p in range(n_pov):
        path = record_state[bounds[p]:bounds[p + 1]]
        if walk.lap_steps[p]:
            # Loops shorter than min_steps * step are walked more than once:
            # keep the first lap only.
            kept = 1 + walk.lap_steps[p] // record_every
            path = np.vstack([path[:kept], walk.lap_end[p][None, :]])
        else:
            # Never left the close_tol ball (a loop of diameter < close_tol,
            # tip at |r| ~ 3): all records lie on it anyway.
            path = np.vstack([path, walk.final_state[p][None, :]])
        path = path[np.r_[True, np.any(np.diff(path, axis=0) != 0.0, axis=1)]]
        winding[p] = loop_winding(path) if walk.closed[p] else 0
        samples[p] = resample_closed_path(path, n_samples)
        if not walk.closed[p]:
            reason.append(NOT_CLOSED)
        elif np.any(winding[p] != 0):
            reason.append(SPLIT)
        else:
            reason.append(VALID)
    return samples, winding, reason


def project_onto_pose(motor: np.ndarray, target_pose: np.ndarray, *, tol: float = 1e-12,
                      max_iter: int = 50, body_arm: Arm = PAPER_ARM):
    """Newton-project motor states onto ``f(m) = target_pose``.

    ``motor`` ``(P, S, J)``, ``target_pose`` ``(P, 3)``. Each iteration takes
    the least-norm correction ``-J^+ r``, so points move across the fibre,
    not along it. Returns the projected states and each one's final pose
    error ``(P, S)`` (``chain_walk.project_onto_pose``).
    """
    return chain_walk.project_onto_pose(motor, target_pose, body_arm, tol=tol,
                                        max_iter=max_iter)


def periodic_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Paper's motor metric: sqrt(sum_k arccos(cos(a_k - b_k))^2)."""
    return np.linalg.norm(np.abs(arm.wrap_angle(np.asarray(a) - np.asarray(b))), axis=-1)


def _periodic_sq_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared paper motor metric between joint-major ``(4, n)`` arrays."""
    diff = a - b
    # Same as arm.wrap_angle (up to the sign at +-pi, squared away) but
    # faster than the float modulo on the walk's hot path.
    diff -= TWO_PI * np.rint(diff * (1.0 / TWO_PI))
    return np.einsum("ij,ij->j", diff, diff)


def _corrected_kernel_step(m: np.ndarray, pose_target: np.ndarray):
    """One Newton correction of joint-major motor states ``m`` ``(4, n)`` onto
    ``f(m) = pose_target`` ``(3, n)``, and the unit kernel direction there.

    This is ``arm.forward``, ``arm.jacobian`` and ``arm.kernel_direction``
    written out for the 3-segment arm with one trigonometric pass (faster per
    step than the generic batched versions; tests check it against arm.py).

    Our addition, not the paper's: plain Euler kernel steps drift off the
    fibre by O(step^2) each, which over one loop exceeds the pose accuracy
    a POV must keep, so every step is followed by the least-norm
    Newton step ``dm = -J^+ (f(m) - f(m_i))`` (``J^+ = J^T (J J^T)^-1``),
    which moves across the fibre, not along it. The Jacobian taken before
    the small correction also gives the kernel.
    """
    theta = m[:3].copy()                     # segment angles, summed in place
    theta[1] += theta[0]
    theta[2] += theta[1]
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    # Tail sums: joint k moves segments k.. (Jacobian column k is
    # (-tail_y_k, tail_x_k, 1); column 4 is (0, 0, 1)).
    tail_x, tail_y = cos_t, sin_t            # summed in place from the end
    tail_x[1] += tail_x[2]
    tail_x[0] += tail_x[1]
    tail_y[1] += tail_y[2]
    tail_y[0] += tail_y[1]
    tx0, tx1, tx2 = tail_x
    ty0, ty1, ty2 = tail_y
    rx = tx0 - pose_target[0]
    ry = ty0 - pose_target[1]
    # The walk is continuous in unwrapped angles and keeps sum(m) = alpha
    # (the kernel sums to zero), so this difference never needs wrapping.
    ra = m.sum(axis=0) - pose_target[2]
    # Signed 3x3 minors of J reduce to cross products of the tails,
    # cross_ij = tail_i x tail_j (arm.kernel_direction).
    c01 = tx0 * ty1 - tx1 * ty0
    c02 = tx0 * ty2 - tx2 * ty0
    c12 = tx1 * ty2 - tx2 * ty1
    kernel = np.stack([c12, -c02, c01, c02 - c01 - c12])
    kernel /= np.sqrt(np.einsum("ij,ij->j", kernel, kernel))
    # Gram matrix G = J J^T (symmetric 3x3) solved by its adjugate.
    g00 = np.einsum("ij,ij->j", tail_y, tail_y)
    g01 = -np.einsum("ij,ij->j", tail_y, tail_x)
    g11 = np.einsum("ij,ij->j", tail_x, tail_x)
    g02 = -tail_y.sum(axis=0)
    g12 = tail_x.sum(axis=0)
    i00 = 4.0 * g11 - g12 * g12
    i01 = g02 * g12 - 4.0 * g01
    i02 = g01 * g12 - g02 * g11
    i11 = 4.0 * g00 - g02 * g02
    i12 = g01 * g02 - g00 * g12
    i22 = g00 * g11 - g01 * g01
    inv_det = 1.0 / (g00 * i00 + g01 * i01 + g02 * i02)
    z0 = (i00 * rx + i01 * ry + i02 * ra) * inv_det
    z1 = (i01 * rx + i11 * ry + i12 * ra) * inv_det
    z2 = (i02 * rx + i12 * ry + i22 * ra) * inv_det
    # dm = J^T z: rows k < 3 get -tail_y_k z0 + tail_x_k z1 + z2, row 3 gets z2.
    corrected = m - z2
    corrected[:3] += tail_y * z0 - tail_x * z1
    return corrected, kernel
