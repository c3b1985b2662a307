"""Hot stages of the representation, each against a straightforward baseline
measured in the same run on the same data (the paper run's POVs):

* Hausdorff matrix (``core.hausdorff.hausdorff_matrix``) vs the blocked
  NumPy brute force of the same formula (``hausdorff_matrix_bruteforce``):
  times, ratio, max abs difference. The fast path (compiled kernel when
  numba is installed) runs on its default threads (2) and on one thread, so
  the ratio can be read both ways; the NumPy path (int16 screen, the
  fallback) is timed too.
* CCA per epoch (``core.cca.CCA``) vs a literal per-step (P, d) NumPy
  transcription of the same cca.m update (``reference_cca``), fed the same
  initial projection, sample order and schedules, so the embeddings must
  agree to rounding.
* Regularisation per iteration (``core.regularize.iterate_regularization``)
  and its averaging step ``regularize_metric`` vs a Python loop over the
  equality sets (``reference_regularize``).
"""
from __future__ import annotations

import time

import numpy as np

from sensorispace_ros.core import cca as cca_module
from sensorispace_ros.core import hausdorff as hausdorff_module
from sensorispace_ros.core.cca import CCA, classical_mds
from sensorispace_ros.core.hausdorff import hausdorff_matrix, hausdorff_matrix_bruteforce
from sensorispace_ros.core.regularize import iterate_regularization, regularize_metric

from bench.child import load


CPU_TIMES: dict = {}


def _timed(fn, repeats: int = 1, name: str | None = None):
    """(result of the last call, list of wall times). With ``name``, the
    smallest process CPU time of a call (all threads) goes to CPU_TIMES[name]:
    on a loaded machine CPU time is the steadier of the two."""
    times, cpus, result = [], [], None
    for _ in range(max(1, repeats)):
        started, cpu = time.perf_counter(), time.process_time()
        result = fn()
        times.append(time.perf_counter() - started)
        cpus.append(time.process_time() - cpu)
    if name:
        CPU_TIMES[name] = min(cpus)
    return result, times


def bench_hausdorff(povs: np.ndarray, repeats: int = 3, brute_repeats: int = 1) -> dict:
    load_before = load()
    hausdorff_matrix(povs[:20])               # compile (or load the cached kernel) first
    fast, fast_t = _timed(lambda: hausdorff_matrix(povs), repeats, "fast")
    single, single_t = _timed(lambda: hausdorff_matrix(povs, n_jobs=1), repeats, "single")
    numpy_path, numpy_t = _timed(lambda: hausdorff_matrix(povs, kernel="numpy"), 1, "numpy")
    brute, brute_t = _timed(lambda: hausdorff_matrix_bruteforce(povs), brute_repeats, "brute")
    return {
        "kernel": "numba" if hausdorff_module.numba_available() else "numpy",
        "numpy_path_s": numpy_t[0], "numpy_path_cpu_s": CPU_TIMES["numpy"],
        "numpy_path_max_abs_diff": float(np.max(np.abs(numpy_path - brute))),
        "povs": list(povs.shape),
        "baseline": "hausdorff_matrix_bruteforce (blocked NumPy float64, 1 thread)",
        "fast_s": min(fast_t), "fast_times_s": fast_t,
        "fast_1thread_s": min(single_t),
        "bruteforce_s": min(brute_t), "bruteforce_times_s": brute_t,
        "ratio": min(brute_t) / min(fast_t),
        "ratio_1thread": min(brute_t) / min(single_t),
        "cpu_s": {"fast": CPU_TIMES["fast"], "fast_1thread": CPU_TIMES["single"],
                  "bruteforce": CPU_TIMES["brute"]},
        "ratio_cpu_1thread": CPU_TIMES["brute"] / CPU_TIMES["single"],
        "max_abs_diff": float(np.max(np.abs(fast - brute))),
        "max_abs_diff_1thread": float(np.max(np.abs(single - brute))),
        "load_before": load_before, "load_after": load(),
    }


def reference_cca(dx: np.ndarray, Y0: np.ndarray, samples: np.ndarray, alpha: np.ndarray,
                  lam: np.ndarray) -> np.ndarray:
    """cca.m's update written plainly on a (P, d) array, one step per sample."""
    Y = Y0.copy()
    floor = 1e-12 * max(float(dx.max()), 1e-300)
    for t, i in enumerate(samples):
        diff = Y - Y[i]
        dy = np.maximum(np.sqrt(np.sum(diff * diff, axis=1)), floor)
        gain = alpha[t] * np.exp(-dy / lam[t]) * (dx[i] / dy - 1.0)
        Y += gain[:, None] * diff
    return Y


def bench_cca(distance: np.ndarray, n_epochs: int = 50, baseline_epochs: int = 2,
              alpha0: float = 0.5, seed: int = 0) -> dict:
    """Per epoch time of CCA in 2-D and 3-D; baseline on ``baseline_epochs``."""
    load_before = load()
    P = distance.shape[0]
    out = {"P": P, "n_epochs": n_epochs, "baseline": "reference_cca (per-step (P, d) NumPy)",
           "dims": {}}
    for d in (2, 3):
        init = classical_mds(distance, d)
        _, fit_t = _timed(lambda: CCA(d, metric="precomputed", n_epochs=n_epochs, alpha0=alpha0,
                                      random_state=seed).fit_transform(distance, init=init))
        # Same schedule as CCA.fit_transform for a short run, then both implementations.
        short = CCA(d, metric="precomputed", n_epochs=baseline_epochs, alpha0=alpha0,
                    random_state=seed)
        Y_fast, short_t = _timed(lambda: short.fit_transform(distance, init=init))
        rng = np.random.default_rng(seed)
        steps = baseline_epochs * P
        samples = rng.integers(P, size=steps)
        fraction = np.arange(steps) / max(steps - 1, 1)
        lambda0 = short.lambda0_
        alpha = alpha0 * 0.01 ** fraction
        lam = lambda0 * (short.lambda_end / lambda0) ** fraction
        Y_ref, ref_t = _timed(lambda: reference_cca(distance, init, samples, alpha, lam))
        per_epoch = fit_t[0] / n_epochs
        ref_per_epoch = ref_t[0] / baseline_epochs
        loop = CCA(d, metric="precomputed", n_epochs=baseline_epochs, alpha0=alpha0,
                   random_state=seed, kernel="numpy")
        Y_loop, loop_t = _timed(lambda: loop.fit_transform(distance, init=init))
        out["dims"][f"{d}d"] = {
            "fit_s": fit_t[0], "per_epoch_ms": 1e3 * per_epoch,
            "baseline_per_epoch_ms": 1e3 * ref_per_epoch,
            "ratio": ref_per_epoch / per_epoch,
            "short_run_per_epoch_ms": 1e3 * short_t[0] / baseline_epochs,
            "max_abs_diff_vs_baseline": float(np.max(np.abs(Y_fast - Y_ref))),
            "kernel": "numba" if cca_module.numba_available() else "numpy",
            "numpy_loop_per_epoch_ms": 1e3 * loop_t[0] / baseline_epochs,
            "max_abs_diff_vs_numpy_loop": float(np.max(np.abs(Y_fast - Y_loop))),
        }
    out["load_before"], out["load_after"] = load_before, load()
    return out


def reference_regularize(distance: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray) -> np.ndarray:
    """Eqs. common_distance / distance_equalities with Python loops."""
    sets: dict = {}
    for (i, j), s in zip(pairs.tolist(), set_ids.tolist()):
        sets.setdefault(s, []).append((i, j))
    means = {s: sum(distance[i, j] for i, j in members) / len(members)
             for s, members in sets.items()}
    targets: dict = {}
    for (i, j), s in zip(pairs.tolist(), set_ids.tolist()):
        targets.setdefault((min(i, j), max(i, j)), []).append(means[s])
    out = distance.copy()
    for (i, j), values in targets.items():
        out[i, j] = out[j, i] = sum(values) / len(values)
    return out


def bench_regularization(distance: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray,
                         n_iterations: int = 10, n_epochs: int = 50, seed: int = 0) -> dict:
    load_before = load()
    fast, fast_t = _timed(lambda: regularize_metric(distance, pairs, set_ids), 5)
    ref, ref_t = _timed(lambda: reference_regularize(distance, pairs, set_ids), 1)
    result, total_t = _timed(lambda: iterate_regularization(
        distance, pairs, set_ids, n_components=2, n_iterations=n_iterations,
        cca_params={"n_epochs": n_epochs}, random_state=seed))
    per_iteration = result.timings_s
    return {
        "pairs": int(len(pairs)), "sets": int(len(np.unique(set_ids))),
        "averaging_ms": 1e3 * min(fast_t), "averaging_baseline_ms": 1e3 * ref_t[0],
        "averaging_ratio": ref_t[0] / min(fast_t),
        "averaging_max_abs_diff": float(np.max(np.abs(fast - ref))),
        "iterations": n_iterations, "cca_epochs": n_epochs,
        "per_iteration_s_2d": float(np.mean(per_iteration)),
        "per_iteration_s_2d_all": [float(t) for t in per_iteration],
        "load_before": load_before, "load_after": load(),
    }
