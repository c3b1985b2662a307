"""The finite-difference step every Jacobian of the naive agent takes after
its rank stage, sized from the noise it measured (``noise.measure_body``):
the float ``fd_step`` on a quiet body; a ``SymmetricStep`` where one
forward difference's noise would tilt the weakest pose direction; an
``AveragedStep`` (every stencil row sensed several times) where even one
symmetric difference's noise hides it, with the search and walk tolerances
that go with its averages (``averaged_search_params``).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive.jacobians import AveragedStep, SymmetricStep
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.structure import BodyStructure


def jacobian_noise(structure: BodyStructure, n_sensors: int, step: float | None = None) -> float:
    """Expected spectral norm of a finite-difference Jacobian's noise
    (sensation per phase) at ``step`` (default: the structure's forward
    step; a ``SymmetricStep`` differences two noisy rows ``2 step`` apart)."""
    step = structure.fd_step if step is None else step
    if step <= 0:
        return 0.0
    spread = np.sqrt(n_sensors) + np.sqrt(structure.n_motors)
    if isinstance(step, AveragedStep):
        return float(structure.noise * np.sqrt(2.0 / step.repeats) * spread / (2.0 * step))
    if isinstance(step, SymmetricStep):
        return float(structure.noise * np.sqrt(2.0) * spread / (2.0 * step))
    return float(structure.noise * np.sqrt(2.0) * spread / step)


# A forward-difference Jacobian whose noise reaches this share of the pose's
# weakest singular value tilts the directions the walks and searches follow.
_WEAK_SHARE = 0.125


def finite_difference_step(params: NaiveParams, structure: BodyStructure,
                           n_sensors: int) -> float:
    """The step every Jacobian of the agent takes: the sized forward step,
    or, where its noise would reach ``_WEAK_SHARE`` of the weakest singular
    value measured at the start (and only there: a symmetric stencil senses
    ``2M + 1`` rows instead of ``M + 1``), a ``SymmetricStep`` where the
    central difference's truncation (``step^2 / (6 L^2)``, relative, ``L``
    the ``fd_curvature_scale``) and its noise are alike, within
    ``fd_max_step``."""
    step = params.fd_step
    if structure.noise <= 0 or structure.weakest <= 0 or structure.gain <= 0 or \
            jacobian_noise(structure, n_sensors, step) <= _WEAK_SHARE * structure.weakest:
        return step
    motor_equivalent = structure.noise * np.sqrt(n_sensors) / structure.gain
    wanted = (3.0 * motor_equivalent * params.fd_curvature_scale ** 2 / np.sqrt(2.0)) ** (1 / 3)
    symmetric = SymmetricStep(max(step, min(params.fd_max_step, wanted)))
    # Averaging pays only for noise that repeats do not repeat (not rounding).
    if jacobian_noise(structure, n_sensors, symmetric) <= structure.weakest or \
            params.jacobian_max_repeats <= 1 or structure.repeat_noise < 0.5 * structure.noise:
        return symmetric
    return averaged_step(params, structure, n_sensors, symmetric)


# Share of the pose's weakest singular value that an averaged Jacobian's
# noise and its truncation error may each reach (``averaged_step``).
_AVERAGED_SHARE = 0.5


def averaged_step(params: NaiveParams, structure: BodyStructure, n_sensors: int,
                  symmetric: float) -> AveragedStep:
    """The ``AveragedStep`` of a body whose weakest pose direction lies below
    the noise of one symmetric difference (no rank test could pass it): the
    step where the central difference's truncation (``step^2 / (6 L^2)``
    of the gain, ``L`` the ``fd_curvature_scale``) reaches
    ``_AVERAGED_SHARE`` of the weakest singular value (a larger step needs
    fewer repeats for the same noise), never below ``symmetric``; sensed as
    many times as brings the Jacobian's noise to that share too, at most
    ``jacobian_max_repeats``."""
    weakest = structure.weakest
    truncated = params.fd_curvature_scale * np.sqrt(6.0 * _AVERAGED_SHARE * weakest
                                                    / structure.gain)
    step = max(float(symmetric), float(truncated))
    single = jacobian_noise(structure, n_sensors, SymmetricStep(step))
    repeats = int(np.ceil((single / (_AVERAGED_SHARE * weakest)) ** 2))
    return AveragedStep(step, int(min(max(repeats, 1), params.jacobian_max_repeats)))


def averaged_search_params(params: NaiveParams, structure: BodyStructure, n_sensors: int,
                           step: float) -> NaiveParams:
    """``params`` with the searches' accepted sensory error tightened to what
    an ``AveragedStep`` leaves: the ``noise_confidence`` quantile of the
    distance between a state's sensation averaged ``repeats`` times and one
    sensing of its target, in motor-equivalent units (over the gain). A
    search whose end lies farther goes on (or stalls) instead of ending
    where only the averaged test of ``confirm`` would reject it. The POV
    walk's predictor tolerance: the motor step the noise of its averaged
    probe asks for through the weakest singular value (instead of one
    sensing's). Unchanged with any other step."""
    if not isinstance(step, AveragedStep) or structure.noise <= 0 or structure.gain <= 0:
        return params
    distance = structure.noise * np.sqrt((1.0 + 1.0 / step.repeats)
                                         * chi2.ppf(params.noise_confidence, n_sensors))
    # A walk's corrections leave what is noise (``jacobians.shrink``); what
    # is left of its farthest probe's is a drift once it reaches that probe's
    # noise through the weakest direction, which the knot interval follows.
    weakest = structure.weakest if structure.weakest > 0 else structure.gain
    drift = structure.noise * np.sqrt(2.0 / walk_step(step).repeats) / weakest
    return replace(params, lm_error_tol=float(distance / structure.gain),
                   pov_predictor_tol=float(min(params.pov_predictor_tol, drift)))


def walk_step(step: float) -> float:
    """The step of a POV walk's Jacobians: ``step``, or for an
    ``AveragedStep`` half its repeats (rounded up): a walk's Jacobians only
    steer it between corrections that leave the noise alone and a
    projection of its samples that filters it along the loop (measured on
    the paper grid at noise 1e-3: a quarter to a half of the rows of the
    full repeats for the same precision of its samples)."""
    if not isinstance(step, AveragedStep):
        return step
    return AveragedStep(float(step), (step.repeats + 1) // 2)
