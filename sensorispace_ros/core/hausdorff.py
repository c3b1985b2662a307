"""Periodic motor metric and the Hausdorff distance between points of view
(paper Sec. "Building a topological representation", Eq. hausdorff).

The motor metric is d(a, b) = sqrt(sum_k arccos(cos(a_k - b_k))^2): each joint
difference is taken on the circle, |wrap(a_k - b_k)| in [0, pi]. We compute
|wrap| from a modulo instead of arccos(cos(.)), which loses ~1e-8 near 0.

``hausdorff_matrix`` is exact (the same float64 numbers as
``hausdorff_matrix_bruteforce``) but does most of its work in 16-bit fixed
point: angles quantised to 2 pi / 2**16 make the periodic wrap free (int16
subtraction wraps around), and int16 differences and float32 squares move
4x and 2x fewer bytes than float64. That screen only *selects* the motor
samples that can be the sup-inf (every one whose screened value is within
the proven screening error of the pair's screened maximum); those samples
are then recomputed exactly in float64. Min and max are exact operations, so
the result equals the brute force to the last bit. Two threads by default.

Pruning by bounding balls of consecutive samples (dual-tree style) was tried
and dropped: POV loops are long (~15 rad) next to the distances between
POVs, so ball radii exceed the Hausdorff values until ~3 samples per ball.

With numba installed (``kernel="auto"``), a compiled kernel does the exact
float64 arithmetic on far fewer sample pairs, and the NumPy path above stays
as fallback and reference (tests compare both, to the bit):

* early break (Taha & Hanbury 2015): the scan for sample a's nearest b stops
  at the first b within the pair's running maximum, since a can no longer
  raise it; the scan starts at the previous a's nearest b (POVs are ordered
  loops, so it moves little);
* a POV is a 1-D loop: with s_j = d(b_j, b_j+1), d(a, b_j+m) >=
  d(a, b_j) - (s_j + ... + s_j+m-1), so the scan jumps over samples that
  cannot beat the best so far, and an a within the running maximum of the
  previous a plus their step is skipped;
* landmarks: H(p, q) >= |H(r, p) - H(r, q)| for the first 64 rows r,
  computed first, starts the running maximum high.

Every skip needs a bound that exceeds the value it discards by a relative
1e-9, far above float64 rounding, so the sup-inf is still the brute force's
float64 number. Timings against the brute force: docs/benchmarks.md,
"kernels".
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

try:
    import numba
except ImportError:             # optional: the NumPy path is the fallback
    numba = None

TWO_PI = 2.0 * np.pi
KERNELS = ("auto", "numpy", "numba")
# Compiled kernel: relative and absolute slack of every pruning bound (far
# above the ~1e-15 rounding of the bounds themselves), and landmark rows.
_BOUND_REL = 1e-9
_BOUND_ABS = 1e-10
_LANDMARKS = 64

# Fixed-point screen: 2 pi <-> 2**16, so int16 subtraction is the periodic wrap.
_SCREEN_BITS = 16
_QUANTUM = TWO_PI / 2.0 ** _SCREEN_BITS
# Bound on |screened - exact| distance: each coordinate's circular difference
# is off by at most one quantum (two roundings of half a quantum), so the
# K-vector by sqrt(K) quanta; float32 squares, K - 1 sums and the sqrt add at
# most 2**-24 relative each, bounded by (K + 3) * 2**-23 (see _block_row).


def motor_distance(a, b) -> np.ndarray:
    """Periodic motor metric d(a, b), broadcasting over leading axes ``(..., K)``."""
    diff = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    wrapped = np.abs((diff + np.pi) % TWO_PI - np.pi)
    return np.sqrt(np.sum(wrapped * wrapped, axis=-1))


def _check_povs(povs) -> np.ndarray:
    povs = np.asarray(povs, dtype=float)
    if povs.ndim != 3:
        raise ValueError(f"povs must have shape (P, N, K), got {povs.shape}")
    if min(povs.shape) < 1:
        raise ValueError(f"povs must hold at least one POV of one sample of one joint, "
                         f"got {povs.shape}")
    if not np.all(np.isfinite(povs)):
        raise ValueError("povs contains NaN or infinite motor values")
    return povs


def _squared_periodic(a_coords: np.ndarray, b_coords: np.ndarray) -> np.ndarray:
    """Squared periodic distance of coordinates already reduced to [0, 2 pi).

    ``a_coords`` and ``b_coords`` are tuples/arrays indexed by coordinate
    first, each item broadcastable. The accumulation order is fixed
    (((w0 + w1) + w2) + w3) so the brute force and the exact recomputation of
    the fast path give identical float64 numbers.
    """
    acc = None
    for a_k, b_k in zip(a_coords, b_coords):
        d = np.abs(a_k - b_k)
        d = np.minimum(d, TWO_PI - d)
        d *= d
        acc = d if acc is None else acc + d
    return acc


def _reduced(povs: np.ndarray) -> np.ndarray:
    return np.mod(povs, TWO_PI)


def directed_hausdorff_pair(A, B) -> float:
    """sup_{a in A} inf_{b in B} d(a, b), literal arccos formula (test oracle)."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    diff = A[:, None, :] - B[None, :, :]
    dist = np.sqrt(np.sum(np.arccos(np.clip(np.cos(diff), -1.0, 1.0)) ** 2, axis=-1))
    return float(dist.min(axis=1).max())


def hausdorff_pair(A, B) -> float:
    """Hausdorff distance of two motor sample sets (paper Eq. hausdorff)."""
    return max(directed_hausdorff_pair(A, B), directed_hausdorff_pair(B, A))


def _row_blocks(P: int, block: int):
    return [(i0, min(i0 + block, P)) for i0 in range(0, P, block)]


def hausdorff_matrix_bruteforce(povs, *, block: int = 8) -> np.ndarray:
    """Every motor-sample pair in float64, blocked over POVs (reference/baseline).

    Same arithmetic as ``_squared_periodic`` (in place, so it is a fair
    baseline): |a - b| on [0, 2 pi) coordinates, min(d, 2 pi - d), squared,
    summed in coordinate order.
    """
    povs = _check_povs(povs)
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    P, N, K = povs.shape
    R = _reduced(povs)
    coords = [np.ascontiguousarray(R[:, :, k]) for k in range(K)]
    H2 = np.zeros((P, P))
    size = (block * N) ** 2
    d_buf, w_buf, acc_buf = np.empty(size), np.empty(size), np.empty(size)
    for i0, i1 in _row_blocks(P, block):
        for j0, j1 in _row_blocks(P, block):
            if j1 <= i0:
                continue
            shape = ((i1 - i0) * N, (j1 - j0) * N)
            n = shape[0] * shape[1]
            d, w, acc = (buf[:n].reshape(shape) for buf in (d_buf, w_buf, acc_buf))
            for k in range(K):
                np.subtract(coords[k][i0:i1].reshape(-1, 1),
                            coords[k][j0:j1].reshape(1, -1), out=d)
                np.abs(d, out=d)
                np.subtract(TWO_PI, d, out=w)
                np.minimum(d, w, out=d)
                if k == 0:
                    np.multiply(d, d, out=acc)
                else:
                    np.multiply(d, d, out=d)
                    acc += d
            sq = acc.reshape(i1 - i0, N, j1 - j0, N)
            H2[i0:i1, j0:j1] = np.maximum(sq.min(axis=3).max(axis=1),
                                          sq.min(axis=1).max(axis=2))
    H2 = np.triu(H2, 1)
    return np.sqrt(H2 + H2.T)


def _quantised(R: np.ndarray) -> np.ndarray:
    """Angles in [0, 2 pi) as int16 fixed point, (K, P, N) contiguous."""
    q = np.rint(R / _QUANTUM).astype(np.int64) % (1 << _SCREEN_BITS)
    q = np.where(q >= 1 << (_SCREEN_BITS - 1), q - (1 << _SCREEN_BITS), q)
    return np.ascontiguousarray(np.moveaxis(q.astype(np.int16), -1, 0))


def _exact_min_sq(coords, pov_a, sample_a, pov_b) -> np.ndarray:
    """Exact squared distance from sample ``sample_a`` of POV ``pov_a`` to the
    nearest sample of POV ``pov_b`` (vectors of candidates); ``coords`` is the
    coordinate-major (K, P, N) copy of the reduced angles."""
    sq = _squared_periodic([c[pov_a, sample_a][:, None] for c in coords],
                           [c[pov_b] for c in coords])
    return sq.min(axis=1)


def _block_row(i0, i1, P, N, RT, Q, block, H2):
    K = Q.shape[0]
    bi = i1 - i0
    abs_quanta = np.sqrt(K) + 0.5
    rel = (K + 3) * 2.0 ** -23
    a_q = [Q[k, i0:i1].reshape(-1, 1) for k in range(K)]
    # Buffers are reused across tiles: fresh multi-MB arrays cost a page
    # fault per 4 KiB on first touch, as much as the kernel's own work.
    size = bi * N * block * N
    diff_buf = np.empty(size, dtype=np.int16)
    sq_buf = np.empty(size, dtype=np.float32)
    acc_buf = np.empty(size, dtype=np.float32)
    for j0 in range(i0, P, block):
        j1 = min(j0 + block, P)
        bj = j1 - j0
        shape = (bi * N, bj * N)
        n = shape[0] * shape[1]
        diff = diff_buf[:n].reshape(shape)
        sq = sq_buf[:n].reshape(shape)
        acc = acc_buf[:n].reshape(shape)
        for k in range(K):
            np.subtract(a_q[k], Q[k, j0:j1].reshape(1, -1), out=diff)
            # A casting copy then an in-place square beats a casting multiply.
            target = acc if k == 0 else sq
            np.copyto(target, diff)
            np.multiply(target, target, out=target)
            if k:
                acc += sq
        acc4 = acc.reshape(bi, N, bj, N)
        row = np.sqrt(acc4.min(axis=3))            # (bi, N, bj): a of I to POV of J
        col = np.sqrt(acc4.min(axis=1))            # (bi, bj, N): b of J to POV of I
        top = np.maximum(row.max(axis=1), col.max(axis=2))          # (bi, bj)
        # A sample can hold the true sup-inf only if its screened value is
        # within twice the screening error of the screened maximum.
        cut = top - 2.0 * (abs_quanta + rel * top)
        if j0 == i0:
            # Self pairs and the lower triangle of a diagonal tile are not needed.
            cut[np.tril_indices(bi, 0, bj)] = np.inf
        ii, aa, jj = np.nonzero(row >= cut[:, None, :])
        exact = np.zeros((bi, bj))
        if ii.size:
            m = _exact_min_sq(RT, i0 + ii, aa, j0 + jj)
            np.maximum.at(exact, (ii, jj), m)
        ii, jj, bb = np.nonzero(col >= cut[:, :, None])
        if bb.size:
            m = _exact_min_sq(RT, j0 + jj, bb, i0 + ii)
            np.maximum.at(exact, (ii, jj), m)
        H2[i0:i1, j0:j1] = exact


def _squared_pair(R, p, i, q, j):
    """Squared periodic distance of sample i of POV p and sample j of POV q,
    with ``_squared_periodic``'s operations in its order (same float64)."""
    acc = 0.0
    for k in range(R.shape[2]):
        d = abs(R[p, i, k] - R[q, j, k])
        w = TWO_PI - d
        if w < d:
            d = w
        acc += d * d
    return acc


def _loop_steps(R):
    """(P, N) distance from each sample to the next one of its loop (cyclic)."""
    P, N, _ = R.shape
    steps = np.empty((P, N))
    for p in range(P):
        for j in range(N):
            steps[p, j] = math.sqrt(_squared_pair(R, p, j, p, (j + 1) % N))
    return steps


def _nearest_within(R, steps, a_pov, i, b_pov, start, cmax):
    """(squared distance, index) of the nearest sample of ``b_pov`` to sample
    ``i`` of ``a_pov``, or of the first one found within ``cmax``; the scan
    goes round the loop from ``start``, jumping over samples that the loop
    steps prove farther than the best so far."""
    N = R.shape[1]
    cmin = np.inf
    best = start
    reach = np.inf
    j = start
    covered = 0
    while covered < N:
        d = _squared_pair(R, a_pov, i, b_pov, j)
        if d < cmin:
            cmin = d
            best = j
            if cmin <= cmax:
                break
            reach = math.sqrt(cmin) * (1.0 + _BOUND_REL) + _BOUND_ABS
        budget = math.sqrt(d) - reach
        j = j + 1 if j + 1 < N else 0
        covered += 1
        while covered < N:
            budget -= steps[b_pov, j - 1 if j > 0 else N - 1]
            if budget <= 0.0:
                break
            j = j + 1 if j + 1 < N else 0
            covered += 1
    return cmin, best


def _pruned_rows(R, steps, rows, landmarks, H2, first_column=0):
    """Squared Hausdorff distances H2[p, q], q > p and q >= ``first_column``,
    for p in ``rows``; rows p >= ``landmarks`` use the rows r < ``landmarks``,
    which must be done (for every q they are used with)."""
    P, N, _ = R.shape
    for r in range(rows.shape[0]):
        p = rows[r]
        for q in range(max(p + 1, first_column), P):
            lower = 0.0
            for m in range(landmarks if p >= landmarks else 0):
                gap = abs(math.sqrt(H2[m, p]) - math.sqrt(H2[m, q]))
                if gap > lower:
                    lower = gap
            lower = lower * (1.0 - _BOUND_REL) - _BOUND_ABS
            cmax = lower * lower if lower > 0.0 else 0.0
            for side in range(2):
                a_pov = p if side == 0 else q
                b_pov = q if side == 0 else p
                nearest = 0
                upper = np.inf          # bound on the current a's distance to b_pov
                below = math.sqrt(cmax) * (1.0 - _BOUND_REL) - _BOUND_ABS
                for i in range(N):
                    if i > 0:
                        upper += steps[a_pov, i - 1]
                        if upper < below:
                            continue
                    cmin, nearest = _nearest_within(R, steps, a_pov, i, b_pov, nearest, cmax)
                    upper = math.sqrt(cmin) * (1.0 + _BOUND_REL) + _BOUND_ABS
                    if cmin > cmax:
                        cmax = cmin
                        below = math.sqrt(cmax) * (1.0 - _BOUND_REL) - _BOUND_ABS
            H2[p, q] = cmax


# Compiled in place (callees are looked up by name at compile time); without
# numba they stay Python: exact, but only usable on tiny inputs (tests).
if numba is not None:
    _jit = numba.njit(nogil=True, cache=True)
    _squared_pair = _jit(_squared_pair)
    _loop_steps = _jit(_loop_steps)
    _nearest_within = _jit(_nearest_within)
    _pruned_rows = _jit(_pruned_rows)


def numba_available() -> bool:
    """True when the compiled kernel can be used."""
    return numba is not None


def _pruned_matrix(R, n_jobs=1, progress=None, rows_per_task=8, landmarks=None):
    """Hausdorff matrix of reduced angles ``R`` (P, N, K) by ``_pruned_rows``:
    the landmark rows first, then the others (``n_jobs`` threads each)."""
    P = R.shape[0]
    landmarks = min(_LANDMARKS if landmarks is None else int(landmarks), P)
    steps = _loop_steps(R)
    H2 = np.zeros((P, P))
    phases = [[np.arange(r0, min(r0 + rows_per_task, stop))
               for r0 in range(start, stop, rows_per_task)]
              for start, stop in ((0, landmarks), (landmarks, P))]
    total = sum(len(tasks) for tasks in phases)
    done = 0
    with ThreadPoolExecutor(max_workers=n_jobs) as pool:
        for tasks in phases:
            futures = [pool.submit(_pruned_rows, R, steps, rows, landmarks, H2, 0)
                       for rows in tasks]
            for fut in futures:
                fut.result()
                done += 1
                if progress is not None:
                    progress(done, total)
    H2 = np.triu(H2, 1)
    return np.sqrt(H2 + H2.T)


class GrowingHausdorffMatrix:
    """The Hausdorff matrix of POVs that arrive a few at a time (the
    representation node receives them during the exploration): ``add`` computes
    the distances of the new POVs to every POV held, so that at the end only
    the last ones are left to do. ``matrix(order)`` equals ``hausdorff_matrix``
    of the same POVs in that order to the bit: every entry is the exact sup-inf
    (the compiled kernel's bounds only skip work), whatever the order or the
    batches it was computed in.

    Needs the compiled kernel (``numba_available()``); the landmarks are the
    first ``_LANDMARKS`` POVs added. Storage grows by doubling: ~8 * P**2 bytes
    at most twice over (paper: 650 POVs, 3.4 MB).
    """

    def __init__(self, n_samples: int, n_motors: int = 4):
        if not numba_available():
            raise RuntimeError("GrowingHausdorffMatrix needs numba (the compiled kernel)")
        self.n_samples, self.n_motors = int(n_samples), int(n_motors)
        self._R = np.zeros((0, self.n_samples, self.n_motors))
        self._steps = np.zeros((0, self.n_samples))
        self._H2 = np.zeros((0, 0))
        self.count = 0

    def _reserve(self, size: int) -> None:
        if size <= len(self._R):
            return
        capacity = max(size, 2 * len(self._R), 16)
        for name, shape in (("_R", (capacity, self.n_samples, self.n_motors)),
                            ("_steps", (capacity, self.n_samples)),
                            ("_H2", (capacity, capacity))):
            old = getattr(self, name)
            grown = np.zeros(shape)
            grown[tuple(slice(0, n) for n in old.shape)] = old
            setattr(self, name, grown)

    def add(self, povs) -> None:
        """Append POVs ``(B, N, K)`` and compute their distances to all held."""
        povs = np.asarray(povs, dtype=float)
        if povs.ndim != 3 or povs.shape[1:] != (self.n_samples, self.n_motors):
            raise ValueError(f"povs must have shape (B, {self.n_samples}, {self.n_motors}), "
                             f"got {povs.shape}")
        if len(povs) == 0:
            return
        if not np.all(np.isfinite(povs)):
            raise ValueError("povs contain NaN or infinite angles")
        first, end = self.count, self.count + len(povs)
        self._reserve(end)
        self._R[first:end] = _reduced(povs)
        R = self._R[:end]                   # contiguous: the first rows of a C array
        self._steps[first:end] = _loop_steps(np.ascontiguousarray(R[first:end]))
        landmarks = min(_LANDMARKS, end)
        # The landmark rows' new columns first (the other rows' bounds use them),
        # then every other row's new columns.
        _pruned_rows(R, self._steps, np.arange(0, landmarks), landmarks, self._H2, first)
        _pruned_rows(R, self._steps, np.arange(landmarks, end), landmarks, self._H2, first)
        self.count = end

    def matrix(self, order=None) -> np.ndarray:
        """``(P, P)`` matrix of the POVs held, rows in the order they were
        added, or in ``order`` (indices into that order, e.g. a sort by id)."""
        H2 = np.triu(self._H2[:self.count, :self.count], 1)
        distance = np.sqrt(H2 + H2.T)
        if order is None:
            return distance
        order = np.asarray(order, dtype=int)
        if sorted(order.tolist()) != list(range(self.count)):
            raise ValueError(f"order must be a permutation of 0..{self.count - 1}")
        return distance[np.ix_(order, order)]


def hausdorff_matrix(povs, *, block: int | None = None, progress=None,
                     n_jobs: int | None = None, kernel: str = "auto") -> np.ndarray:
    """Symmetric (P, P) Hausdorff matrix of POVs ``(P, N, K)`` under the
    periodic motor metric, zero diagonal; equal to the brute force to the bit.

    ``block`` POVs per tile (memory ~ 10 * (block * N)**2 bytes per worker,
    independent of P), ``progress(done, total)`` is called after each block
    row, ``n_jobs`` threads (default: 2, or 1 on a single core) share the
    rows; NumPy and the compiled kernel release the GIL. ``kernel``: "auto"
    (numba if installed, else NumPy), "numpy" or "numba"; the same bits.
    """
    povs = _check_povs(povs)
    P, N, K = povs.shape
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    if kernel == "numba" and not numba_available():
        raise ValueError("kernel 'numba' needs the numba package, which is not installed")
    if block is None:
        block = max(1, min(P, 800 // N if N <= 800 else 1))
    if block < 1:
        raise ValueError(f"block must be >= 1, got {block}")
    n_jobs = min(2, os.cpu_count() or 1) if n_jobs is None else int(n_jobs)
    if n_jobs < 1:
        raise ValueError(f"n_jobs must be >= 1, got {n_jobs}")
    R = _reduced(povs)
    if kernel != "numpy" and numba_available():
        return _pruned_matrix(np.ascontiguousarray(R), n_jobs, progress)
    Q = _quantised(R)
    RT = np.ascontiguousarray(np.moveaxis(R, -1, 0))
    H2 = np.zeros((P, P))
    rows = _row_blocks(P, block)
    total = len(rows)
    if n_jobs == 1:
        for done, (i0, i1) in enumerate(rows, 1):
            _block_row(i0, i1, P, N, RT, Q, block, H2)
            if progress is not None:
                progress(done, total)
    else:
        with ThreadPoolExecutor(max_workers=n_jobs) as pool:
            futures = [pool.submit(_block_row, i0, i1, P, N, RT, Q, block, H2)
                       for i0, i1 in rows]
            for done, fut in enumerate(futures, 1):
                fut.result()
                if progress is not None:
                    progress(done, total)
    H2 = np.triu(H2, 1)
    return np.sqrt(H2 + H2.T)
