"""The agent's representation of its points of view, from its own data only.

Hausdorff metric of the POVs, CCA projections in 2-D and 3-D, and the metric
regularisation iterations by the equality sets. No ground truth enters here.
The 2-D and 3-D chains (CCA, then regularise -> CCA) are independent and each
draws from its own seeded streams, so they run in two processes with the
same bits as in one (``chain_pool``).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from sensorispace_ros.core.seeding import rng_for
from sensorispace_ros.offline.chain_pool import can_fork
from sensorispace_ros.offline.timing import timed_stage

if TYPE_CHECKING:
    from concurrent.futures import Executor

DIMENSIONS = {"2d": 2, "3d": 3}            # the paper's embeddings, always made
MAX_MEASURED_DIMENSION = 10
STAGES = ("before", "after")


@dataclass
class Representation:
    """The agent's internal representation of its points of view."""

    distance: np.ndarray                         # (P, P) Hausdorff metric
    before: dict                                 # "2d" -> (P, 2), "3d" -> (P, 3), "<d>d"
    iterations: dict                             # "2d" -> (I, P, 2), one per iteration
    set_spread: dict                             # "2d" -> (I,) per iteration
    timings_s: dict = field(default_factory=dict)

    @property
    def after(self) -> dict:
        return {dim: emb[-1] for dim, emb in self.iterations.items()}

    def embedding(self, dim: str, stage: str) -> np.ndarray:
        return self.before[dim] if stage == "before" else self.iterations[dim][-1]

    def space_dimension(self) -> float:
        """The intrinsic dimension of the points of view under the agent's own
        metric (``core.intrinsic_dimension``); NaN with too few of them."""
        from sensorispace_ros.core.intrinsic_dimension import K_RANGE, mle_dimension

        if len(self.distance) <= K_RANGE[1]:
            return float("nan")
        return mle_dimension(self.distance)


def random_state(seed: int, stream: str) -> int:
    """An integer seed for scikit-learn style ``random_state`` arguments."""
    return int(rng_for(seed, stream).integers(2 ** 31 - 1))


def cca_params(cfg: dict) -> dict:
    cca = cfg["representation"]["cca"]
    return {"n_epochs": cca["n_epochs"], "alpha0": cca["alpha0"], "lambda0": cca["lambda0"]}


def build_representation(povs: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray, cfg: dict,
                         seed: int, progress=None, processes: int | None = None,
                         executor: Executor | None = None,
                         distance: np.ndarray | None = None) -> Representation:
    """Hausdorff metric, CCA before regularisation and the regularisation
    iterations, in 2-D, 3-D and the measured dimension (``embedding_dimensions``),
    from the agent's data only. ``povs``
    ``(P, N, joints)`` are joint angles (a joint's period mapped to 2 pi).

    ``distance``: the Hausdorff matrix of ``povs`` when the caller already has
    it (the representation node grows it while the POVs arrive,
    ``core.hausdorff.GrowingHausdorffMatrix``: the same bits); computed here
    otherwise.

    ``processes``: how many processes run the 2-D and 3-D chains (default:
    2 on a multi-core machine, when the caller can fork safely: see
    ``chain_pool.can_fork``). ``executor``: the caller's own pool for the
    chains (a process that must not fork, e.g. ``start_chain_pool``'s), in
    place of ``processes``. The result depends on neither.
    """
    from sensorispace_ros.core.hausdorff import hausdorff_matrix

    povs = np.asarray(povs, dtype=float)
    if povs.ndim != 3 or povs.shape[2] < 1 or len(povs) < 4:
        raise ValueError(f"povs must have shape (P >= 4, N, joints), got {povs.shape}")
    workers = _chain_workers(processes, executor)
    if distance is not None:
        distance = np.asarray(distance, dtype=float)
        if distance.shape != (len(povs), len(povs)):
            raise ValueError(f"distance must have shape ({len(povs)}, {len(povs)}), "
                             f"got {distance.shape}")
    timings: dict = {}
    with timed_stage(progress, "hausdorff", timings):
        if distance is None:
            distance = hausdorff_matrix(povs, progress=progress)
    chains, block = {}, {}
    dimensions = embedding_dimensions(distance, cfg)
    with timed_stage(progress, "cca_regularization", block, total=len(dimensions)):
        _run_chains(chains, dimensions, workers, executor, distance, pairs, set_ids, cfg, seed,
                    progress)
    timings.update(_chain_timings(chains, block["cca_regularization"], workers))
    return Representation(distance=distance,
                          before={name: chain["before"] for name, chain in chains.items()},
                          iterations={name: chain["iterations"] for name, chain in chains.items()},
                          set_spread={name: chain["spread"] for name, chain in chains.items()},
                          timings_s=timings)


def embedding_dimensions(distance: np.ndarray, cfg: dict) -> dict:
    """The embeddings to make: the paper's 2-D and 3-D, and with
    ``representation.measured_dimension`` the dimension of space the agent
    measures in its own metric (``Representation.space_dimension``) when it
    is another, as ``"<d>d"``."""
    dimensions = dict(DIMENSIONS)
    if cfg["representation"]["measured_dimension"]:
        estimate = Representation(distance, {}, {}, {}).space_dimension()
        found = int(round(estimate)) if np.isfinite(estimate) else 0
        if 1 <= found <= MAX_MEASURED_DIMENSION and found not in dimensions.values():
            dimensions[f"{found}d"] = found
    return dimensions


def _chain_workers(processes: int | None, executor: Executor | None) -> int:
    """How many processes run the chains (the argument checks of ``build_representation``)."""
    if processes is not None and executor is not None:
        raise ValueError("processes and executor: give one of them, not both")
    if executor is not None:
        return len(DIMENSIONS)
    if processes is None:
        return min(len(DIMENSIONS), os.cpu_count() or 1) if can_fork() else 1
    if int(processes) < 1:
        raise ValueError(f"processes must be >= 1, got {processes!r}")
    return int(processes)


def _run_chains(chains: dict, dimensions: dict, workers: int, executor: Executor | None,
                distance: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray, cfg: dict,
                seed: int, progress=None) -> None:
    """Every dimension's chain into ``chains``: on ``executor``, on a forked
    pool of ``workers`` processes, or in this process."""
    if executor is not None:
        _chains_in(executor, chains, dimensions, distance, pairs, set_ids, cfg, seed, progress)
    elif workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        context = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(max_workers=min(workers, len(dimensions)),
                                 mp_context=context) as pool:
            _chains_in(pool, chains, dimensions, distance, pairs, set_ids, cfg, seed, progress)
    else:
        for name, n_components in dimensions.items():
            chains[name] = _dimension_chain(distance, pairs, set_ids, cfg, seed, name,
                                            n_components)
            if progress is not None:
                progress(len(chains), len(dimensions))


def _chain_timings(chains: dict, block_s: float, workers: int) -> dict:
    """Wall times that add up to the chains' block: ``cca`` the CCA before
    regularisation (in parallel: until every chain had it), ``regularization``
    the rest; each chain's own times as ``cca_<dim>``, ``regularization_<dim>``."""
    cca_times = [chain["timings_s"]["cca"] for chain in chains.values()]
    timings = {"cca": max(cca_times) if workers > 1 else sum(cca_times)}
    timings["regularization"] = block_s - timings["cca"]
    for name, chain in chains.items():
        for step in ("cca", "regularization"):
            timings[f"{step}_{name}"] = chain["timings_s"][step]
    return timings


def _chains_in(pool: Executor, chains: dict, dimensions: dict, distance: np.ndarray,
               pairs: np.ndarray, set_ids: np.ndarray, cfg: dict, seed: int,
               progress=None) -> None:
    """Every dimension's chain as a task of ``pool``, into ``chains``."""
    futures = {name: pool.submit(_dimension_chain, distance, pairs, set_ids, cfg, seed, name,
                                 n_components)
               for name, n_components in dimensions.items()}
    for name, future in futures.items():
        chains[name] = future.result()
        if progress is not None:
            progress(len(chains), len(dimensions))


def _dimension_chain(distance: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray, cfg: dict,
                     seed: int, name: str, n_components: int) -> dict:
    """CCA of the Hausdorff metric, then the regularisation iterations, in
    ``n_components`` dimensions (a process of its own in build_representation)."""
    from sensorispace_ros.core.cca import CCA
    from sensorispace_ros.core.regularize import iterate_regularization, set_spread

    started = time.perf_counter()
    estimator = CCA(n_components=n_components, metric="precomputed", init="mds",
                    random_state=random_state(seed, f"cca.{name}"), **cca_params(cfg))
    before = np.asarray(estimator.fit_transform(distance))
    cca_s = time.perf_counter() - started
    result = iterate_regularization(
        distance, pairs, set_ids, n_components=n_components,
        n_iterations=cfg["representation"]["regularization"]["iterations"],
        cca_params=cca_params(cfg), random_state=random_state(seed, f"regularization.{name}"),
        init=None)
    # result.set_spread[k] is measured before iteration k's averaging
    # (k = 0: the Hausdorff metric); add the spread after the last one.
    spread = np.asarray([*result.set_spread, set_spread(result.distances, pairs, set_ids)],
                        dtype=float)
    return {"before": before,
            "iterations": np.stack([np.asarray(e) for e in result.embeddings]),
            "spread": spread,
            "timings_s": {"cca": cca_s,
                          "regularization": time.perf_counter() - started - cca_s}}
