"""Curvilinear Component Analysis (Demartines & Herault 1997) as a
scikit-learn estimator (paper Sec. "Building a topological representation":
the points of view are projected to 2-D and 3-D with CCA).

The update rule and schedules follow the SOM Toolbox ``cca.m``: one random
sample i per step pulls or pushes every other projection j along
Y_j - Y_i by exp(-dy_ij / lambda) * (dx_ij / dy_ij - 1); step size alpha and
neighbourhood radius lambda decay geometrically ("potency curve") from
alpha0 to alpha0 / 100 and from lambda0 to ``lambda_end`` over
n_epochs * P steps. Where cca.m starts from a random or PCA projection, the
default here is classical MDS: reproducible, and closer to the answer.

The step loop runs compiled with numba when it is installed (``kernel``
"auto"): the same IEEE operations in the same order, so the projection is
bit-identical to the NumPy loop where NumPy's exp is the C library's
(``core.numpy_math``); the NumPy loop stays as fallback and reference.
"""
from __future__ import annotations

import math
import numbers
import sys
import warnings

import numpy as np
from scipy.linalg import eigh
from scipy.spatial.distance import pdist, squareform
from sklearn.base import BaseEstimator, _fit_context
from sklearn.utils import check_array, check_symmetric
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import validate_data
from threadpoolctl import threadpool_limits

_METRICS = ("euclidean", "precomputed")
KERNELS = ("auto", "numpy", "numba")

try:
    import numba
except ImportError:             # optional: the NumPy loop is the fallback
    numba = None


def _cca_steps(YT, dx, samples, alpha, neg_inv_lambda, floor):
    """CCA updates for ``samples`` in turn, in place on ``YT`` (d, P).

    Written for numba; the arithmetic (operations and their order) is that of
    the NumPy loop ``_numpy_steps``, element by element.
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
    """The Generator behind ``random_state``: an int or None seeds
    ``numpy.random.default_rng``, a Generator is used (and advanced) as is, a
    legacy RandomState seeds a new Generator with one draw."""
    if random_state is None or isinstance(random_state, numbers.Integral):
        return np.random.default_rng(random_state)
    if isinstance(random_state, np.random.Generator):
        return random_state
    if isinstance(random_state, np.random.RandomState):
        return np.random.default_rng(random_state.randint(np.iinfo(np.int32).max))
    raise ValueError("random_state must be None, an int, a numpy Generator or a RandomState, "
                     f"got {type(random_state).__name__}")


def _check_distance_properties(D: np.ndarray, name: str) -> np.ndarray:
    """``D`` (a validated 2-D float array) if it is square, non-negative and
    symmetric (``sklearn.utils.check_symmetric``'s tolerance); else a
    ValueError naming ``name`` and the reason."""
    if D.shape[0] != D.shape[1]:
        raise ValueError(f"{name} must be a square (P, P) distance matrix, got shape {D.shape}")
    if np.any(D < 0):
        raise ValueError(f"Negative values in data passed to {name}: distances are >= 0 "
                         f"(min {D.min():.3g})")
    try:
        check_symmetric(D, raise_exception=True)
    except ValueError:
        asym = float(np.max(np.abs(D - D.T)))
        raise ValueError(f"{name} is not symmetric (max |D - D.T| = {asym:.3g})") from None
    return D


def check_distance_matrix(X, name: str = "X") -> np.ndarray:
    """A (P, P) float64 C-contiguous distance matrix (P >= 2), or a
    ValueError saying what is wrong: sparse, complex, NaN or infinite
    entries, not square, negative or not symmetric."""
    try:
        D = check_array(X, dtype=np.float64, ensure_min_samples=2, input_name=name)
    except ValueError as error:
        if name in str(error):
            raise
        raise ValueError(f"{name}: {error}") from None
    return np.ascontiguousarray(_check_distance_properties(D, name))


def _looks_like_distances(X: np.ndarray) -> bool:
    """Square, zero diagonal, non-negative and symmetric."""
    return (X.shape[0] == X.shape[1] and not np.any(np.diagonal(X)) and not np.any(X < 0)
            and np.allclose(X, X.T))


def classical_mds(distance, n_components: int) -> np.ndarray:
    """Torgerson MDS: top eigenvectors of the double-centred squared distances.

    Signs are fixed (largest-magnitude coordinate of each axis positive) so
    the result does not depend on the LAPACK build. Only the top eigenpairs
    are computed, on one BLAS thread: a threaded OpenBLAS ``eigh`` is many
    times slower on a machine whose cores are busy.
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


def _numpy_steps(YT, dx, samples, alpha, neg_inv_lambda, floor, epoch_done=None):
    """The CCA updates of ``_cca_steps`` as NumPy ufunc calls, in place on
    ``YT`` (d, P); ``epoch_done(epoch)`` after every P steps.

    Coordinates-major layout: every update is a few ufunc calls on
    contiguous rows, cheaper than one einsum on (P, d).
    """
    d, P = YT.shape
    diff = np.empty_like(YT)
    sq = np.empty_like(YT)
    dy = np.empty(P)
    gain = np.empty(P)
    for t in range(samples.shape[0]):
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
        if epoch_done is not None and (t + 1) % P == 0:
            epoch_done((t + 1) // P)


def _compiled_steps(YT, dx, samples, alpha, neg_inv_lambda, floor, epoch_done=None):
    """``_cca_steps`` compiled, one call per epoch of P steps."""
    P = YT.shape[1]
    for epoch in range(samples.shape[0] // P):
        span = slice(epoch * P, (epoch + 1) * P)
        _cca_steps_compiled(YT, dx, samples[span], alpha[span], neg_inv_lambda[span], floor)
        if epoch_done is not None:
            epoch_done(epoch + 1)


class CCA(BaseEstimator):
    """Curvilinear Component Analysis.

    A non-linear projection of P points to ``n_components`` dimensions that
    keeps the short distances first: each step picks one point i at random
    and moves every projection j along Y_j - Y_i so that its distance to i
    gets closer to the input one, weighted by exp(-dy_ij / lambda). The step
    size decays from ``alpha0`` to ``alpha0 / 100`` and the radius lambda
    from ``lambda0`` to ``lambda_end`` over ``n_epochs * P`` steps. There is
    no out-of-sample ``transform``: ``fit_transform`` gives the projection.

    Parameters
    ----------
    n_components : int, default=2
        Dimension of the projection.
    metric : {"euclidean", "precomputed"}, default="euclidean"
        "euclidean": X is a (P, n_features) data matrix and the input
        distances are Euclidean. "precomputed": X is a (P, P) symmetric,
        non-negative distance matrix, used as is.
    n_epochs : int, default=50
        Training length; each epoch is P single-sample updates.
    alpha0 : float, default=0.5
        Initial step size (it decays to ``alpha0 / 100``).
    lambda0 : float or None, default=None
        Initial neighbourhood radius, in the units of the distances. None:
        3 times the largest standard deviation of the initial projection's
        coordinates (as cca.m).
    init : {"mds", "random"} or array-like of shape (P, n_components), \
default="mds"
        Initial projection: classical MDS of the distances, uniform random
        in a box as wide as the largest distance, or the given coordinates.
        The ``init`` argument of ``fit`` and ``fit_transform`` overrides it.
    random_state : int, numpy.random.Generator, numpy.random.RandomState \
or None, default=None
        Sample order and random initial projection. An int or None seeds
        ``numpy.random.default_rng``; a Generator is used (and advanced) as
        is; a RandomState seeds a new Generator with one draw.
    verbose : int, default=0
        When positive, one line on stderr per epoch.
    lambda_end : float, default=0.01
        Final neighbourhood radius, in the units of the distances.
    kernel : {"auto", "numpy", "numba"}, default="auto"
        The step loop: compiled with numba ("auto" when numba is installed)
        or NumPy ufuncs. Both do the same IEEE operations in the same order.

    Attributes
    ----------
    embedding_ : ndarray of shape (P, n_components)
        The projection.
    stress_ : float
        Weighted stress 1/2 sum_ij (dx_ij - dy_ij)^2 exp(-dy_ij / lambda_end)
        of the projection (computed when read).
    n_iter_ : int
        Epochs run.
    lambda0_ : float
        The initial radius used.
    n_features_in_ : int
        Number of columns of X seen during ``fit`` (P when precomputed).
    feature_names_in_ : ndarray of shape (n_features_in_,)
        Column names of X, when X has string column names.

    See Also
    --------
    sklearn.manifold.MDS : metric multidimensional scaling.
    sklearn.manifold.Isomap : projection of geodesic distances.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial.distance import pdist, squareform
    >>> from sensorispace_ros.core.cca import CCA
    >>> X = np.random.default_rng(0).uniform(size=(50, 3))
    >>> cca = CCA(n_components=2, n_epochs=5, random_state=0)
    >>> Y = cca.fit_transform(X)
    >>> Y.shape, cca.n_features_in_
    ((50, 2), 3)
    >>> D = squareform(pdist(X))
    >>> Y_from_D = CCA(2, metric="precomputed", n_epochs=5, random_state=0).fit_transform(D)
    >>> bool(np.array_equal(Y_from_D, Y))
    True
    """

    _parameter_constraints: dict = {
        "n_components": [Interval(numbers.Integral, 1, None, closed="left")],
        "metric": [StrOptions(set(_METRICS))],
        "n_epochs": [Interval(numbers.Integral, 1, None, closed="left")],
        "alpha0": [Interval(numbers.Real, 0, None, closed="neither")],
        "lambda0": [Interval(numbers.Real, 0, None, closed="neither"), None],
        "init": [StrOptions({"mds", "random"}), "array-like"],
        "random_state": ["random_state", np.random.Generator],
        "verbose": ["verbose"],
        "lambda_end": [Interval(numbers.Real, 0, None, closed="neither")],
        "kernel": [StrOptions(set(KERNELS))],
    }

    def __init__(self, n_components=2, *, metric="euclidean", n_epochs=50, alpha0=0.5,
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

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.pairwise = self.metric == "precomputed"
        tags.input_tags.positive_only = self.metric == "precomputed"
        return tags

    def fit(self, X, y=None, init=None):
        """Compute the projection of the points of X (``embedding_``).

        Takes the parameters of ``fit_transform``; returns the fitted
        estimator.
        """
        self.fit_transform(X, init=init)
        return self

    @_fit_context(prefer_skip_nested_validation=True)
    def fit_transform(self, X, y=None, init=None):
        """Compute the projection of the points of X and return it.

        Parameters
        ----------
        X : array-like of shape (P, n_features) or (P, P)
            Points, or their distance matrix when ``metric="precomputed"``.
        y : Ignored
            Not used, present for API consistency by convention.
        init : {"mds", "random"}, array-like of shape (P, n_components) or \
None, default=None
            Initial projection; None: the estimator's ``init``.

        Returns
        -------
        embedding : ndarray of shape (P, n_components)
            The projection (``embedding_``).
        """
        if self.kernel == "numba" and not numba_available():
            raise ValueError("kernel 'numba' needs the numba package, which is not installed")
        dx = self._distances(X)
        rng = _generator(self.random_state)
        Y = self._initial(self.init if init is None else init, dx, rng)
        lambda0 = self._initial_radius(Y, dx)
        samples, alpha, neg_inv_lambda = self._schedules(dx.shape[0], lambda0, rng)
        # Coincident projections: cca.m replaces dy = 0 by 1; any positive
        # floor works since their Dy = 0 anyway.
        floor = 1e-12 * max(float(dx.max()), 1e-300)
        steps = _compiled_steps if self.kernel != "numpy" and numba_available() else _numpy_steps
        YT = np.ascontiguousarray(Y.T)
        steps(YT, dx, samples, alpha, neg_inv_lambda, floor,
              self._report_epoch if self.verbose else None)
        self.embedding_ = np.ascontiguousarray(YT.T)
        self.lambda0_ = lambda0
        self.n_iter_ = int(self.n_epochs)
        self._fitted_distances = dx
        return self.embedding_

    def _distances(self, X) -> np.ndarray:
        X = validate_data(self, X, dtype=np.float64, ensure_min_samples=2)
        if self.metric == "precomputed":
            return np.ascontiguousarray(_check_distance_properties(X, "X"))
        if _looks_like_distances(X):
            warnings.warn("X is square, symmetric and non-negative with a zero diagonal, like a "
                          "distance matrix, but metric='euclidean' reads its rows as points; "
                          "pass metric='precomputed' if it holds distances", UserWarning,
                          stacklevel=4)
        return np.ascontiguousarray(squareform(pdist(X, metric="euclidean")))

    def _initial(self, init, dx, rng) -> np.ndarray:
        P, d = dx.shape[0], self.n_components
        if isinstance(init, str):
            if init == "mds":
                return np.ascontiguousarray(classical_mds(dx, d))
            if init == "random":
                half_width = max(float(dx.max()), 1e-12) / 2.0
                return rng.uniform(-half_width, half_width, size=(P, d))
            raise ValueError(f"init must be 'mds', 'random' or an array, got {init!r}")
        # A copy: the steps move the projection in place.
        Y = check_array(init, dtype=np.float64, ensure_2d=False, copy=True, input_name="init")
        if Y.shape != (P, d):
            raise ValueError(f"init array must have shape {(P, d)}, got {Y.shape}")
        return np.ascontiguousarray(Y)

    def _initial_radius(self, Y, dx) -> float:
        if self.lambda0 is not None:
            return self.lambda0
        lambda0 = 3.0 * float(np.max(np.std(Y, axis=0)))
        return lambda0 if lambda0 > 0 else max(float(dx.max()), 1e-12)

    def _schedules(self, P, lambda0, rng):
        """Sample order, step sizes and -1 / radius, one per step."""
        steps = int(self.n_epochs) * P
        samples = rng.integers(P, size=steps)
        fraction = np.arange(steps) / max(steps - 1, 1)
        alpha = self.alpha0 * 0.01 ** fraction
        neg_inv_lambda = -1.0 / (lambda0 * (self.lambda_end / lambda0) ** fraction)
        return samples, alpha, neg_inv_lambda

    def _report_epoch(self, epoch: int) -> None:
        print(f"CCA epoch {epoch}/{self.n_epochs}", file=sys.stderr)

    @property
    def stress_(self) -> float:
        # On demand: P^2 exponentials, and the pipeline never reads it.
        if not hasattr(self, "_fitted_distances"):
            raise AttributeError("stress_ is available after fit")
        return cca_stress(self._fitted_distances, self.embedding_, self.lambda_end)
