"""Curvilinear Component Analysis (Demartines & Herault 1997) as a
scikit-learn style estimator (paper Sec. "Building a topological
representation": POVs are projected to 2-D and 3-D with CCA).

The update rule and schedules follow the SOM Toolbox ``cca.m``: one random
sample i per step pulls or pushes every other projection j along
Y_j - Y_i by exp(-dy_ij / lambda) * (dx_ij / dy_ij - 1); step size alpha and
neighbourhood radius lambda decay geometrically ("potency curve") from
alpha0 to alpha0 / 100 and from lambda0 to ``lambda_end`` over
n_epochs * P steps. Where cca.m starts from a random or PCA projection, the
default here is classical MDS (issue #2: CCA from MDS is reproducible and
needs fewer epochs).

The step loop runs compiled with numba when it is installed (``kernel``
"auto"): the same IEEE operations in the same order, so the projection is
bit-identical to the NumPy loop where NumPy's exp is the C library's
(``core.numpy_math``; on an AVX-512 machine NumPy's own exp moves the last
bits), which stays as fallback and reference (tests compare both).
Measured x2-3 on P = 650 (the NumPy loop is ~15 ufunc calls of P elements
per step, mostly call overhead).
"""
from __future__ import annotations

import math
import numbers
import sys

import numpy as np
from scipy.linalg import eigh
from scipy.spatial.distance import pdist, squareform
from sklearn.base import BaseEstimator
from threadpoolctl import threadpool_limits

_METRICS = ("precomputed", "euclidean")
KERNELS = ("auto", "numpy", "numba")

try:
    import numba
except ImportError:             # optional: the NumPy loop is the fallback
    numba = None


def _cca_steps(YT, dx, samples, alpha, neg_inv_lambda, floor):
    """CCA updates for ``samples`` in turn, in place on ``YT`` (d, P).

    Written for numba; the arithmetic (operations and their order) is that of
    the NumPy loop in ``CCA.fit_transform``, element by element.
    """
    d, P = YT.shape
    yi = np.empty(d)
    for t in range(samples.shape[0]):
        i = samples[t]
        for k in range(d):
            yi[k] = YT[k, i]
        scale = neg_inv_lambda[t]
        step = alpha[t]
        for j in range(P):
            acc = 0.0
            for k in range(d):
                diff = YT[k, j] - yi[k]
                acc += diff * diff
            dy = math.sqrt(acc)
            if dy < floor:
                dy = floor
            gain = (dx[i, j] / dy - 1.0) * math.exp(dy * scale) * step
            for k in range(d):
                YT[k, j] = YT[k, j] + (YT[k, j] - yi[k]) * gain


_cca_steps_compiled = None if numba is None else numba.njit(nogil=True, cache=True)(_cca_steps)


def numba_available() -> bool:
    """True when the compiled step loop can be used."""
    return _cca_steps_compiled is not None


def _generator(random_state) -> np.random.Generator:
    if random_state is None or isinstance(random_state, numbers.Integral):
        return np.random.default_rng(random_state)
    if isinstance(random_state, np.random.Generator):
        return random_state
    raise ValueError("random_state must be None, an int or a numpy Generator, "
                     f"got {type(random_state).__name__}")


def check_distance_matrix(X, name: str = "X") -> np.ndarray:
    """A (P, P) float64 distance matrix, or a ValueError saying what is wrong."""
    D = np.asarray(X, dtype=float)
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise ValueError(f"{name} must be a square (P, P) distance matrix, got shape {D.shape}")
    if D.shape[0] < 2:
        raise ValueError(f"{name} must describe at least 2 points, got {D.shape[0]}")
    if not np.all(np.isfinite(D)):
        raise ValueError(f"{name} contains NaN or infinite distances")
    if np.any(D < 0):
        raise ValueError(f"{name} contains negative distances (min {D.min():.3g})")
    scale = max(float(D.max()), 1e-300)
    asym = float(np.max(np.abs(D - D.T)))
    if asym > 1e-9 * scale:
        raise ValueError(f"{name} is not symmetric (max |D - D.T| = {asym:.3g})")
    return np.ascontiguousarray(D)


def classical_mds(distance, n_components: int) -> np.ndarray:
    """Torgerson MDS: top eigenvectors of the double-centred squared distances.

    Signs are fixed (largest-magnitude coordinate of each axis positive) so
    the result does not depend on the LAPACK build. Only the top eigenpairs
    are computed, on one BLAS thread: on a busy 2-core machine a threaded
    OpenBLAS eigh of 500 points took 9.5 s instead of 0.24 s.
    """
    D = np.asarray(distance, dtype=float)
    P = D.shape[0]
    sq = D * D
    B = -0.5 * (sq - sq.mean(axis=0, keepdims=True) - sq.mean(axis=1, keepdims=True) + sq.mean())
    k = min(n_components, P)
    with threadpool_limits(limits=1, user_api="blas"):
        values, vectors = eigh(B, subset_by_index=[P - k, P - 1])
    values = np.clip(values[::-1], 0.0, None)
    vectors = vectors[:, ::-1]
    signs = np.sign(vectors[np.argmax(np.abs(vectors), axis=0), np.arange(k)])
    signs[signs == 0] = 1.0
    Y = vectors * signs * np.sqrt(values)
    if k < n_components:
        Y = np.hstack([Y, np.zeros((P, n_components - k))])
    return Y


def cca_stress(distance, embedding, lam: float) -> float:
    """CCA's weighted stress 1/2 sum_ij (dx_ij - dy_ij)^2 exp(-dy_ij / lam)."""
    dy = squareform(pdist(embedding))
    return float(np.sum((distance - dy) ** 2 * np.exp(-dy / lam)) / 2.0)


class CCA(BaseEstimator):
    """Curvilinear Component Analysis.

    Parameters
    ----------
    n_components : output dimension.
    metric : "precomputed" (X is a (P, P) distance matrix) or "euclidean"
        (X is a (P, D) data matrix).
    n_epochs : training length; each epoch is P single-sample updates.
    alpha0 : initial step size (decays to alpha0 / 100).
    lambda0 : initial neighbourhood radius; default 3 * max std of the
        initial embedding (cca.m).
    init : "mds" (classical MDS), "random", or a (P, n_components) array.
    lambda_end : final neighbourhood radius (cca.m uses 0.01), in the units
        of the distances.
    random_state : None, int or numpy Generator (sample order, random init).
    kernel : "auto" (numba if installed, else NumPy), "numpy" or "numba":
        the step loop; both give the same bits.

    Attributes
    ----------
    embedding_ : (P, n_components) projection.
    stress_ : weighted stress at the final lambda.
    n_iter_ : epochs run.
    lambda0_ : the initial radius actually used.
    """

    def __init__(self, n_components=2, *, metric="precomputed", n_epochs=50, alpha0=0.5,
                 lambda0=None, init="mds", random_state=None, verbose=0, lambda_end=0.01,
                 kernel="auto"):
        self.n_components = n_components
        self.metric = metric
        self.n_epochs = n_epochs
        self.alpha0 = alpha0
        self.lambda0 = lambda0
        self.init = init
        self.random_state = random_state
        self.verbose = verbose
        self.lambda_end = lambda_end
        self.kernel = kernel

    def fit(self, X, y=None):
        self.fit_transform(X, y)
        return self

    def _check_params(self):
        if not isinstance(self.n_components, numbers.Integral) or self.n_components < 1:
            raise ValueError(f"n_components must be a positive integer, got {self.n_components!r}")
        if self.metric not in _METRICS:
            raise ValueError(f"metric must be one of {_METRICS}, got {self.metric!r}")
        if not isinstance(self.n_epochs, numbers.Integral) or self.n_epochs < 1:
            raise ValueError(f"n_epochs must be a positive integer, got {self.n_epochs!r}")
        if not self.alpha0 > 0:
            raise ValueError(f"alpha0 must be > 0, got {self.alpha0!r}")
        if self.lambda0 is not None and not self.lambda0 > 0:
            raise ValueError(f"lambda0 must be > 0 or None, got {self.lambda0!r}")
        if not self.lambda_end > 0:
            raise ValueError(f"lambda_end must be > 0, got {self.lambda_end!r}")
        if self.kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {self.kernel!r}")
        if self.kernel == "numba" and not numba_available():
            raise ValueError("kernel 'numba' needs the numba package, which is not installed")

    def _distances(self, X) -> np.ndarray:
        if self.metric == "precomputed":
            return check_distance_matrix(X)
        data = np.asarray(X, dtype=float)
        if data.ndim != 2 or data.shape[0] < 2:
            raise ValueError(f"X must be a (P, D) data matrix with P >= 2, got shape {data.shape}")
        if not np.all(np.isfinite(data)):
            raise ValueError("X contains NaN or infinite values")
        return np.ascontiguousarray(squareform(pdist(data, metric=self.metric)))

    def _initial(self, init, dx, rng) -> np.ndarray:
        P, d = dx.shape[0], self.n_components
        if isinstance(init, str):
            if init == "mds":
                return classical_mds(dx, d)
            if init == "random":
                half_width = max(float(dx.max()), 1e-12) / 2.0
                return rng.uniform(-half_width, half_width, size=(P, d))
            raise ValueError(f"init must be 'mds', 'random' or an array, got {init!r}")
        Y = np.array(init, dtype=float)
        if Y.shape != (P, d):
            raise ValueError(f"init array must have shape {(P, d)}, got {Y.shape}")
        if not np.all(np.isfinite(Y)):
            raise ValueError("init array contains NaN or infinite values")
        return Y

    def fit_transform(self, X, y=None, init=None):
        self._check_params()
        dx = self._distances(X)
        rng = _generator(self.random_state)
        Y = np.ascontiguousarray(self._initial(self.init if init is None else init, dx, rng))
        P = dx.shape[0]
        lambda0 = self.lambda0
        if lambda0 is None:
            lambda0 = 3.0 * float(np.max(np.std(Y, axis=0)))
            if lambda0 <= 0:
                lambda0 = max(float(dx.max()), 1e-12)
        steps = int(self.n_epochs) * P
        samples = rng.integers(P, size=steps)
        fraction = np.arange(steps) / max(steps - 1, 1)
        alpha = self.alpha0 * 0.01 ** fraction
        neg_inv_lambda = -1.0 / (lambda0 * (self.lambda_end / lambda0) ** fraction)
        # Coincident projections: cca.m replaces dy = 0 by 1; any positive
        # floor works since their Dy = 0 anyway.
        floor = 1e-12 * max(float(dx.max()), 1e-300)
        if self.kernel != "numpy" and numba_available():
            YT = np.ascontiguousarray(Y.T)
            for epoch in range(int(self.n_epochs)):
                span = slice(epoch * P, (epoch + 1) * P)
                _cca_steps_compiled(YT, dx, samples[span], alpha[span], neg_inv_lambda[span],
                                    floor)
                if self.verbose:
                    print(f"CCA epoch {epoch + 1}/{self.n_epochs}", file=sys.stderr)
            return self._finish(dx, np.ascontiguousarray(YT.T), lambda0)
        # Coordinates-major layout: every update is a few ufunc calls on
        # contiguous rows (measured 19 us/step for P=650, d=2, vs 33 with
        # einsum on (P, d)).
        YT = np.ascontiguousarray(Y.T)
        diff = np.empty_like(YT)
        sq = np.empty_like(YT)
        dy = np.empty(P)
        gain = np.empty(P)
        d = YT.shape[0]
        for t in range(steps):
            i = samples[t]
            np.subtract(YT, YT[:, i:i + 1], out=diff)
            np.multiply(diff, diff, out=sq)
            if d == 1:
                np.copyto(dy, sq[0])
            else:
                np.add(sq[0], sq[1], out=dy)
                for k in range(2, d):
                    np.add(dy, sq[k], out=dy)
            np.sqrt(dy, out=dy)
            np.maximum(dy, floor, out=dy)
            np.divide(dx[i], dy, out=gain)
            np.subtract(gain, 1.0, out=gain)
            np.multiply(dy, neg_inv_lambda[t], out=dy)
            np.exp(dy, out=dy)
            np.multiply(gain, dy, out=gain)
            np.multiply(gain, alpha[t], out=gain)
            np.multiply(diff, gain, out=diff)
            np.add(YT, diff, out=YT)
            if self.verbose and (t + 1) % P == 0:
                print(f"CCA epoch {(t + 1) // P}/{self.n_epochs}", file=sys.stderr)
        return self._finish(dx, np.ascontiguousarray(YT.T), lambda0)

    def _finish(self, dx, Y, lambda0):
        self.embedding_ = Y
        self.lambda0_ = lambda0
        self.n_iter_ = int(self.n_epochs)
        self._fitted_distances = dx
        return Y

    @property
    def stress_(self) -> float:
        # On demand: P^2 exponentials per fit, ~10% of a regularisation
        # iteration at P = 2645, and the pipeline never reads it.
        if not hasattr(self, "_fitted_distances"):
            raise AttributeError("stress_ is available after fit")
        return cca_stress(self._fitted_distances, self.embedding_, self.lambda_end)
