"""A strategy end to end: strategy, representation, evaluation, run directory."""
from __future__ import annotations

import time
from pathlib import Path

from sensorispace_ros import config as config_mod
from sensorispace_ros.core.arm import Arm
from sensorispace_ros.evaluation.ground_truth import RunTruth
from sensorispace_ros.evaluation.naive import join_naive_run
from sensorispace_ros.evaluation.runs import evaluate_output, write_without_representation
from sensorispace_ros.offline.pov_assembly import MIN_POVS
from sensorispace_ros.offline.representation import build_representation
from sensorispace_ros.offline.strategies import STRATEGIES, run_strategy


def reproduce(cfg: dict, strategy: str = "paper", seed: int | None = None,
              out_dir: str | Path = "results/run", progress=None, figures: bool = True) -> dict:
    """Run a strategy end to end; write metrics.json, arrays.npz, figures/*.png.

    Returns the metrics (nested dict, as written). ``seed`` overrides
    ``cfg["seed"]``; ``figures=False`` overrides ``output.figures`` (the
    configuration written with the metrics says so).
    """
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")
    overrides = {}
    if seed is not None:
        overrides["seed"] = seed
    if not figures:
        overrides["output.figures"] = False
    if overrides:
        cfg = config_mod.load_config(overrides={**config_mod.flatten(cfg), **overrides})
    else:
        cfg = config_mod.validate_config(cfg)
    seed = cfg["seed"]

    started = time.perf_counter()
    produced = run_strategy(cfg, strategy, seed, progress)
    truth = RunTruth(cfg, produced.world)
    if produced.naive_run is not None:
        join_naive_run(produced, truth)
    if len(produced.povs) < MIN_POVS:
        return write_without_representation(produced, cfg, out_dir, strategy, truth, started)
    # The Hausdorff metric reads motor values as angles (a period = 2 pi).
    angles = Arm.from_config(cfg["arm"]).to_radians(produced.povs)
    representation = build_representation(angles, produced.pairs, produced.set_ids, cfg,
                                          seed, progress)
    return evaluate_output(produced, representation, cfg, out_dir, strategy,
                           {**produced.timings_s, **representation.timings_s}, progress,
                           started=started, truth=truth)
