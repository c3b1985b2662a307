"""Numbers that say how good a representation of the sensor positions is.

- trustworthiness: are the embedding's neighbours true neighbours?
- continuity: are true neighbours kept as neighbours in the embedding?
- spearman: rank agreement of all pairwise distances (the paper's metric
  comparison figures, as one number).
- affine_residual: how far the embedding is from an affine image of the true
  positions (the paper: after regularisation the 2-D representation "is an
  affine transformation" of the sensor positions).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.distance import pdist
from scipy.stats import spearmanr
from sklearn.manifold import trustworthiness as _sk_trustworthiness


def _points(name: str, X) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim != 2:
        raise ValueError(f"{name} must be a (P, D) array, got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return X


def _pair(true_positions, embedding):
    T = _points("true_positions", true_positions)
    Y = _points("embedding", embedding)
    if T.shape[0] != Y.shape[0]:
        raise ValueError(f"true_positions has {T.shape[0]} points, embedding {Y.shape[0]}")
    return T, Y


def _check_neighbors(n_neighbors: int, P: int):
    if not 1 <= n_neighbors < P / 2:
        raise ValueError(f"n_neighbors must be in [1, P/2) = [1, {P / 2}), got {n_neighbors}")


def trustworthiness(true_positions, embedding, n_neighbors: int = 5) -> float:
    T, Y = _pair(true_positions, embedding)
    _check_neighbors(n_neighbors, T.shape[0])
    return float(_sk_trustworthiness(T, Y, n_neighbors=n_neighbors))


def continuity(true_positions, embedding, n_neighbors: int = 5) -> float:
    """Trustworthiness with the roles of truth and embedding swapped."""
    T, Y = _pair(true_positions, embedding)
    _check_neighbors(n_neighbors, T.shape[0])
    return float(_sk_trustworthiness(Y, T, n_neighbors=n_neighbors))


def spearman(true_positions, embedding) -> float:
    T, Y = _pair(true_positions, embedding)
    if T.shape[0] < 3:
        raise ValueError("spearman needs at least 3 points")
    return float(spearmanr(pdist(T), pdist(Y)).statistic)


def affine_residual(embedding, true_positions) -> float:
    """||residual of the least-squares affine map embedding -> truth||_F
    / ||truth - its mean||_F (0: the embedding is an affine image)."""
    T, Y = _pair(true_positions, embedding)
    design = np.hstack([Y, np.ones((Y.shape[0], 1))])
    coef, *_ = np.linalg.lstsq(design, T, rcond=None)
    spread = np.linalg.norm(T - T.mean(axis=0))
    if spread == 0:
        raise ValueError("true_positions are all equal: the residual is undefined")
    return float(np.linalg.norm(design @ coef - T) / spread)


def _stable(value: float) -> float:
    return float(f"{value:.12g}")


def quality_report(embedding, true_positions, n_neighbors: int = 5) -> dict:
    """The four numbers as plain floats rounded to 12 significant digits, so
    metrics.json does not change in the last bits between identical runs.
    Fewer than ``2 n_neighbors + 1`` points (a run that found few POVs) rank
    the largest neighbourhood they allow."""
    n_neighbors = min(int(n_neighbors), max(1, (len(np.asarray(true_positions)) - 1) // 2))
    return {
        "trustworthiness": _stable(trustworthiness(true_positions, embedding, n_neighbors)),
        "continuity": _stable(continuity(true_positions, embedding, n_neighbors)),
        "spearman": _stable(spearman(true_positions, embedding)),
        "affine_residual": _stable(affine_residual(embedding, true_positions)),
    }
