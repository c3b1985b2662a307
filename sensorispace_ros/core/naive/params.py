"""Parameters of the naive strategy (the ``naive:`` section of the config).

Their names, defaults, checks and meanings are ``config.NAIVE``
(``config.SCHEMA["naive"]``), the table of every parameter; ``NaiveParams``
is what the agent reads. ``config`` is pure Python (no rclpy), so core may
import it.
"""
from __future__ import annotations

import copy
from dataclasses import asdict, dataclass, field

import numpy as np

from sensorispace_ros import config


def _default(name: str):
    return field(default=config.NAIVE[name].default)


@dataclass(frozen=True)
class NaiveParams:
    """The naive agent's parameters (meanings and ranges: ``config.NAIVE``).

    Construction checks every value with ``config.validate_naive``: a bad
    one raises ``config.ConfigError`` (a ValueError) such as
    ``naive.lm_max_step: must be a finite number > 0.0, got 0``.
    """

    n_samples: int = _default("n_samples")
    n_samples_surface: int = _default("n_samples_surface")
    fd_step: float = _default("fd_step")
    noise_repeats: int = _default("noise_repeats")
    noise_confidence: float = _default("noise_confidence")
    fd_curvature_scale: float = _default("fd_curvature_scale")
    fd_max_step: float = _default("fd_max_step")
    rank_noise_gap: float = _default("rank_noise_gap")
    structure_max_repeats: int = _default("structure_max_repeats")
    cloud_step: float = _default("cloud_step")
    cloud_pairs: int = _default("cloud_pairs")
    cloud_max_pairs: int = _default("cloud_max_pairs")
    cloud_rank_gap: float = _default("cloud_rank_gap")
    jacobian_max_repeats: int = _default("jacobian_max_repeats")
    accept_repeats: int = _default("accept_repeats")
    accept_max_repeats: int = _default("accept_max_repeats")
    confirm_rounds: int = _default("confirm_rounds")
    pose_precision: float = _default("pose_precision")
    pose_precision_povs: int = _default("pose_precision_povs")
    pool_sensings: int = _default("pool_sensings")
    averaged_targets: int = _default("averaged_targets")
    target_singular: float = _default("target_singular")
    lost_row_retries: int = _default("lost_row_retries")
    structure_probes: int = _default("structure_probes")
    structure_radius: float = _default("structure_radius")
    rank_min_gap: float = _default("rank_min_gap")
    pov_initial_step: float = _default("pov_initial_step")
    pov_min_step: float = _default("pov_min_step")
    pov_max_step: float = _default("pov_max_step")
    pov_predictor_tol: float = _default("pov_predictor_tol")
    pov_max_queries: int = _default("pov_max_queries")
    pov_polish_iterations: int = _default("pov_polish_iterations")
    pov_closure_tol: float = _default("pov_closure_tol")
    pov_sample_tol: float = _default("pov_sample_tol")
    pov_surface_step: float = _default("pov_surface_step")
    pov_surface_max_queries: int = _default("pov_surface_max_queries")
    lm_max_iterations: int = _default("lm_max_iterations")
    lm_stall_iterations: int = _default("lm_stall_iterations")
    lm_error_tol: float = _default("lm_error_tol")
    lm_motor_tol: float = _default("lm_motor_tol")
    lm_max_step: float = _default("lm_max_step")
    lm_initial_damping: float = _default("lm_initial_damping")
    lm_restarts: int = _default("lm_restarts")
    match_tol: float = _default("match_tol")
    match_separation: float = _default("match_separation")
    match_ratio: float = _default("match_ratio")
    rank_ratio: float = _default("rank_ratio")
    pattern_ratio: float = _default("pattern_ratio")
    min_singular: float = _default("min_singular")
    max_snapshots: int = _default("max_snapshots")
    snapshot_patience: int = _default("snapshot_patience")
    unconfirmed_attempts: int = _default("unconfirmed_attempts")
    unconfirmed_max_povs: int = _default("unconfirmed_max_povs")
    chained_anchors: bool = _default("chained_anchors")
    probe_grid: int = _default("probe_grid")
    probe_starts: int = _default("probe_starts")
    frontier_attempts: int = _default("frontier_attempts")
    frontier_give_way: bool = _default("frontier_give_way")
    frontier_skip_split: bool = _default("frontier_skip_split")
    frontier_holes: bool = _default("frontier_holes")
    match_discrepancy: bool = _default("match_discrepancy")
    equality_snapshots: int = _default("equality_snapshots")
    confirm_checks: int = _default("confirm_checks")
    remember_sensations: bool = _default("remember_sensations")
    remember_split_povs: bool = _default("remember_split_povs")
    clock_sweep_budget: int = _default("clock_sweep_budget")
    clock_sweep_first: int = _default("clock_sweep_first")
    clock_equality_changes: int = _default("clock_equality_changes")
    clock_equality_budget: int = _default("clock_equality_budget")
    clock_translated_pairs: int = _default("clock_translated_pairs")
    clock_walk_attempts: int = _default("clock_walk_attempts")
    clock_brief_walk: bool = _default("clock_brief_walk")
    clock_search_in_turn: bool = _default("clock_search_in_turn")
    clock_search_turns: int = _default("clock_search_turns")
    clock_search_probe_first: bool = _default("clock_search_probe_first")
    clock_sentinel_rows: int = _default("clock_sentinel_rows")
    clock_pov_predictor_tol: float = _default("clock_pov_predictor_tol")
    clock_pov_polish_iterations: int = _default("clock_pov_polish_iterations")
    clock_pov_checked_samples: int = _default("clock_pov_checked_samples")
    clock_pov_knots_per_step: int = _default("clock_pov_knots_per_step")
    clock_pov_secant_calls: int = _default("clock_pov_secant_calls")
    clock_unconfirmed_when_lost: bool = _default("clock_unconfirmed_when_lost")
    clock_unconfirmed_min_rate: float = _default("clock_unconfirmed_min_rate")
    clock_stop_ratio: float = _default("clock_stop_ratio")
    clock_stop_window: int = _default("clock_stop_window")
    clock_hole_targets: bool = _default("clock_hole_targets")
    clock_hole_attempts: int = _default("clock_hole_attempts")
    lattice_sets: bool = _default("lattice_sets")
    lattice_support: int = _default("lattice_support")
    relax_povs: bool = _default("relax_povs")

    def __post_init__(self):
        # Also fails ("naive.<name>: missing") if a schema entry has no field here.
        for name, value in config.validate_naive(asdict(self)).items():
            object.__setattr__(self, name, value)

    @classmethod
    def from_mapping(cls, values: dict | None) -> "NaiveParams":
        """The parameters of a (partial) ``naive`` section; an unknown key is
        a ``ConfigError`` naming it."""
        merged = {**config.defaults()["naive"], **(values or {})}
        return cls(**config.validate_naive(merged))

    def with_counts(self, **counts: int) -> "NaiveParams":
        """These parameters with ``counts`` (integers >= 0 the agent works
        out as it runs) in place, not checked again: ``dataclasses.replace``
        checks every parameter, which costs more than a reaction's matching."""
        changed = copy.copy(self)
        for name, value in counts.items():
            if not isinstance(value, (int, np.integer)) or value < 0:
                raise ValueError(f"naive.{name}: must be an integer >= 0, got {value!r}")
            object.__setattr__(changed, name, int(value))
        return changed
