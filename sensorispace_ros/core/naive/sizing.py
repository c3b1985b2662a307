"""The naive agent's measure of itself, and the tolerances it sizes from it.

Before it explores, the agent senses its start state and the states around
it (``noise.measure_noise``, then ``structure.measure_structure``): how
noisy a sensation is, which finite-difference step rises clearly above that
noise, its pose rank and its sensory gain. Every tolerance that would
otherwise expect exact repeats is then the larger of its parameter (the
float64 round-off regime: a noiseless body keeps its parameters exactly)
and what the measured noise explains:

* the finite-difference step: where the truncation error of a forward
  difference and the noise it divides by the step are alike
  (``sized_fd_step``);
* compensation acceptance: two sensings of one motor state differ by a
  residual whose squared norm over ``2 sd^2`` is chi-square with ``S``
  degrees of freedom; its ``noise_confidence`` quantile, in
  motor-equivalent units (over the gain), is the accepted sensory error;
* the Gauss-Newton step such a residual asks for, through the pose's
  weakest singular value at the state in question: the accepted motor
  residual of a search (``noise_step``); through the median one measured at
  the start, the POV samples' tolerance; the walk's predictor aims above it;
* sweep matching and dedupe compare sensations of poses found by different
  searches, in chains whose accepted errors add up: ``_CHAIN`` times the
  accepted sensory error (a chain's sum of random errors grows as the
  square root of its length);
* the smallest accepted singular value of a rank test: above the spectral
  norm of a forward-difference Jacobian's noise, so a blank sensation
  (a Jacobian of pure noise) never passes.

When the noise hides the pose rank at one sensing per row, the rank probes
are sensed again and averaged (``structure_max_repeats`` at most).
"""
from __future__ import annotations

import contextlib
from dataclasses import replace

import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive.noise import measure_noise
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.structure import BodyStructure, measure_structure

# Accepted sensory errors a match may add up: chains of a few hundred
# compensations (their random errors grow as the square root of the length).
_CHAIN = 16.0


def sized_fd_step(params: NaiveParams, noise_sd: float, slope: float, n_sensors: int) -> float:
    """The forward-difference step (phase) for a per-receptor noise
    ``noise_sd`` and a sensory ``slope`` (sensation per phase): the step
    where truncation (``step / fd_curvature_scale``, relative) and noise
    (the motor-equivalent noise over the step) are alike."""
    if slope <= 0 or noise_sd <= 0:
        return params.fd_step
    motor_equivalent = noise_sd * np.sqrt(n_sensors) / slope
    wanted = np.sqrt(2.0 * motor_equivalent * params.fd_curvature_scale)
    return float(max(params.fd_step, min(params.fd_max_step, wanted)))


def measure_body(body, center: np.ndarray, params: NaiveParams):
    """Noise, then structure (at the step sized from the noise, probes
    averaged while the noise hides the rank). Returns ``(BodyStructure,
    sized NaiveParams)``; every row goes through ``body.sense``."""
    n_sensors = int(body.n_sensors)
    noise = measure_noise(body, center, repeats=params.noise_repeats,
                          line_rows=params.noise_repeats)
    step = sized_fd_step(params, noise.sd, noise.slope, n_sensors)
    noisy = step > params.fd_step
    repeats, revealed = 1, -1
    while True:
        # Repeats are sensed anew, not recalled from what was sensed before.
        with getattr(body, "fresh", contextlib.nullcontext)():
            structure = measure_structure(body, center, fd_step=step,
                probes=params.structure_probes, radius=params.structure_radius,
                min_gap=params.rank_min_gap, repeats=repeats,
                noise_sd=averaged_sd(noise, repeats) if noisy else None,
                noise_gap=params.rank_noise_gap)
        # Averaging removes only the part of the noise that repeats do not
        # repeat; noise hides the weakest directions, so averaging goes on
        # while it reveals more of them (or the probes disagree).
        if not noisy or noise.repeat_sd == 0 or 4 * repeats > params.structure_max_repeats \
                or (structure.votes == structure.probes and structure.pose_rank <= revealed):
            break
        revealed, repeats = structure.pose_rank, 4 * repeats
    structure = replace(structure, noise=noise.sd, fd_step=step)
    return structure, sized_params(params, structure, n_sensors)


def averaged_sd(noise, repeats: int) -> float:
    """Per-receptor sd of a sensation averaged over ``repeats`` sensings: the
    random part (``repeat_sd``) shrinks, the part that repeats exactly
    (rounding, quantisation) stays."""
    # Repeats that spread about as much as the ladder sees: all of it random.
    fixed = 0.0 if noise.repeat_sd >= 0.5 * noise.sd else noise.sd ** 2 - noise.repeat_sd ** 2
    return float(np.sqrt(noise.repeat_sd ** 2 / repeats + fixed))


def sized_params(params: NaiveParams, structure: BodyStructure, n_sensors: int) -> NaiveParams:
    """``params`` with every exact-repeat tolerance raised to what the
    measured noise explains (the module docstring)."""
    sd, rank = structure.noise, structure.pose_rank
    if sd <= 0 or rank < 1 or structure.gain <= 0:
        return replace(params, fd_step=max(params.fd_step, structure.fd_step))
    quantile = params.noise_confidence
    residual = sd * np.sqrt(2.0 * chi2.ppf(quantile, n_sensors))
    sensory = 2.0 * residual / structure.gain
    weakest = structure.weakest if structure.weakest > 0 else structure.gain
    motor = 2.0 * sd * np.sqrt(2.0 * chi2.ppf(quantile, rank)) / weakest
    # Matches and dedupe compare sensations of poses found by different
    # searches, each within the accepted error of its target, in chains
    # (an anchor is an earlier compensation) whose errors add up.
    match_tol = max(params.match_tol, _CHAIN * sensory)
    return replace(
        params, fd_step=max(params.fd_step, structure.fd_step),
        lm_error_tol=max(params.lm_error_tol, sensory),
        pov_sample_tol=max(params.pov_sample_tol, motor),
        pov_predictor_tol=max(params.pov_predictor_tol, 2.0 * motor),
        match_tol=match_tol, match_separation=max(params.match_separation, 4.0 * match_tol))


def noise_step(params: NaiveParams, structure: BodyStructure) -> float:
    """Twice the ``noise_confidence`` quantile of the part of a residual
    between two sensings that lies in the pose's ``rank`` directions
    (sensation units): over a state's ``rank``-th singular value, the
    Gauss-Newton step a search may keep there."""
    if structure.noise <= 0 or structure.pose_rank < 1:
        return 0.0
    chi = chi2.ppf(params.noise_confidence, structure.pose_rank)
    return float(2.0 * structure.noise * np.sqrt(2.0 * chi))


def jacobian_noise(structure: BodyStructure, n_sensors: int) -> float:
    """Expected spectral norm of a forward-difference Jacobian's noise
    (sensation per phase) at the agent's step."""
    if structure.fd_step <= 0:
        return 0.0
    return float(structure.noise * np.sqrt(2.0) * (np.sqrt(n_sensors)
                                                    + np.sqrt(structure.n_motors))
                 / structure.fd_step)
