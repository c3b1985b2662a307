"""Parameters of the naive strategy (the ``naive:`` section of the config)."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np


@dataclass(frozen=True)
class NaiveParams:
    """Parameters of the naive strategy (``naive:`` section of the config).

    POV walk: ``pov_*`` (see ``points_of_view.sample_sensory_points_of_view``).
    Compensation: ``lm_*`` (see ``compensation.compensate``); besides the
    resting state, ``lm_restarts`` remembered states are tried per target.
    ``lm_initial_damping`` is small (nearly Gauss-Newton steps,
    ``lm_max_step`` bounds them) and a search stops when its error has not
    halved in ``lm_stall_iterations`` iterations: a larger damping or a
    longer patience costs more search calls for the same POVs (see
    docs/benchmarks.md). ``lm_error_tol`` and ``lm_motor_tol`` are tight
    because matches between sweeps rely on compensating poses being exact (a
    pose error e shows as a sensation error ~e).
    Sensation matching: ``match_tol`` (two compensations of the same pose
    through different anchor chains sense alike well within it, lattice
    neighbours differ by far more), ``match_separation`` (uniqueness
    radius), ``rank_ratio`` and ``min_singular`` (rank-3 test of the sensory
    Jacobian).
    Anchors: ``max_snapshots`` kept, dropped after ``snapshot_patience``
    events without a match or a compensation; at most
    ``unconfirmed_attempts`` anchors of unconfirmed snapshots (most recent
    first) are searched per event, and only from snapshots that knew fewer
    than ``unconfirmed_max_povs`` POVs. ``frontier_attempts``: other rows of
    the most recent confirmed snapshot searched per event (see
    ``NaiveAgent._frontier_requests``). Matches of the ``equality_snapshots``
    most recent snapshots are all rank-tested and become equality sets;
    older snapshots are confirmed with at most ``confirm_checks`` rank tests.
    ``remember_sensations``: a call asking only for motor states already
    sensed since the last change is answered from memory (the same bits; see
    ``sense_memory.SensedSinceChange``); false sends every call.
    ``remember_split_povs``: keep one motor state of every POV whose walk
    came back split, sweep it with the known POVs, and do not walk again a
    solution that senses what it senses (``NaiveAgent._search``); false
    walks every new solution. Both flags leave the POVs and compensations
    unchanged; they only save ``sense`` calls.
    """

    n_samples: int = 100
    fd_step: float = 1e-6
    pov_initial_step: float = 0.05
    pov_min_step: float = 1e-3
    pov_max_step: float = 0.15
    pov_predictor_tol: float = 1e-3
    pov_max_queries: int = 5000
    pov_polish_iterations: int = 2
    lm_max_iterations: int = 40
    lm_stall_iterations: int = 3
    lm_error_tol: float = 1e-10
    lm_motor_tol: float = 1e-8
    lm_max_step: float = 0.5
    lm_initial_damping: float = 1e-7
    lm_restarts: int = 2
    match_tol: float = 1e-6
    match_separation: float = 1e-4
    rank_ratio: float = 1e-3
    min_singular: float = 1e-4
    max_snapshots: int = 12
    snapshot_patience: int = 20
    unconfirmed_attempts: int = 4
    unconfirmed_max_povs: int = 100
    frontier_attempts: int = 8
    equality_snapshots: int = 2
    confirm_checks: int = 3
    remember_sensations: bool = True
    remember_split_povs: bool = True

    def __post_init__(self):
        positive_reals = ("fd_step", "pov_initial_step", "pov_min_step", "pov_max_step",
                          "pov_predictor_tol", "lm_error_tol", "lm_motor_tol", "lm_max_step",
                          "lm_initial_damping",
                          "match_tol", "match_separation", "rank_ratio")
        for name in positive_reals:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not np.isfinite(value) or value <= 0:
                raise ValueError(f"naive.{name}: must be a finite number > 0, got {value!r}")
        if isinstance(self.min_singular, bool) or not np.isfinite(self.min_singular) \
                or self.min_singular < 0:
            raise ValueError(f"naive.min_singular: must be a finite number >= 0, got "
                             f"{self.min_singular!r}")
        integers = {"n_samples": 2, "pov_max_queries": 1, "pov_polish_iterations": 0,
                    "lm_max_iterations": 1, "lm_restarts": 1, "max_snapshots": 1,
                    "snapshot_patience": 1, "unconfirmed_attempts": 0,
                    "unconfirmed_max_povs": 0, "lm_stall_iterations": 1,
                    "frontier_attempts": 0, "equality_snapshots": 0, "confirm_checks": 1}
        for name, minimum in integers.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                    or value < minimum:
                raise ValueError(f"naive.{name}: must be an integer >= {minimum}, got {value!r}")
        for name in ("remember_sensations", "remember_split_povs"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"naive.{name}: must be true or false, got "
                                 f"{getattr(self, name)!r}")
        if not self.pov_min_step <= self.pov_initial_step <= self.pov_max_step:
            raise ValueError("naive.pov_initial_step: must lie in [pov_min_step, pov_max_step], "
                             f"got {self.pov_initial_step!r}")
        if not self.match_tol < self.match_separation:
            raise ValueError(f"naive.match_tol: must be < match_separation "
                             f"({self.match_separation!r}), got {self.match_tol!r}")

    @classmethod
    def from_mapping(cls, values: dict | None) -> "NaiveParams":
        values = dict(values or {})
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"naive.{unknown[0]}: unknown parameter")
        return cls(**values)

    def as_dict(self) -> dict:
        return asdict(self)
