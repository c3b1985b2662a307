"""How noisy the naive agent's sensations are, measured by the agent itself.

A real sensor adds noise, rounds its outputs (float32, an ADC's steps) and
loses frames; a real joint lands near, not at, the commanded value, which
shows in the sensations as more noise. The agent is told none of this. It
senses, once, in one ``sense`` call:

* the start state several times: the spread of the repeats is the random
  part of the noise (joint imprecision included; of the repeats after a
  change of the world among them, ``repeat_step``);
* short straight lines through the start with steps on a ladder from tiny
  to coarse: second differences along a line remove the smooth signal (up
  to the step squared times its curvature) and keep the errors. A
  deterministic error (rounding to fixed steps, to float32) repeats
  exactly, so the repeats miss it; along a line whose steps move the
  signal over several rounding steps it looks like noise of about
  step/sqrt(12). Line steps that leave most outputs unchanged (within one
  rounding step) say nothing and are skipped; the finest informative line
  step gives the estimate.

Every spread is robust (``noise_spread``): heavy tails, a few wild outputs
and lost rows (non-finite, left out and counted) do not move it. Where the
repeats and the lines see one random noise their two estimates are pooled;
elsewhere the larger stands. The estimate is a per-receptor standard
deviation in the units of the sensations; float64 round-off of the outputs
is its floor, so a noiseless body measures 1e-16 to 1e-14 and nothing the
agent sizes from it changes.

``measure_body`` then measures the structure at a finite-difference step
sized from the noise, and every tolerance that would expect exact repeats
becomes the larger of its parameter and what the noise explains
(``sized_params``). The rank probes are sensed anew and averaged, twice
as many times each round, while what the rank leaves uncounted holds a
direction the averaging budget (``structure_max_repeats``) would count
(``averaged_structure``).
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive.jacobians import AveragedStep, SymmetricStep
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.noise_spread import (clipped_variance, ladder_spread,
                                                      ladder_steps, line_slope,
                                                      noise_rows, output_lattice, random_noise,
                                                      repeat_spread)
from sensorispace_ros.core.naive.repeat_step import last_world_start
from sensorispace_ros.core.naive.structure import (BodyStructure, measure_structure,
                                                   probe_rows, probe_structure,
                                                   repeat_variance, rounded_structure)

@dataclass(frozen=True)
class SensoryNoise:
    """The agent's measure of its sensory noise (``measure_noise``).

    ``sd`` per-receptor standard deviation of one sensation (sensation
    units): ``repeat_sd`` (the same motor state sensed again) and
    ``ladder_sd`` (second differences along short lines) pooled where they
    agree on one random noise, else the larger (``noise_spread``), at least
    the float64 round-off of the outputs. ``lost_fraction`` the share of
    sensed rows that came back non-finite; ``slope`` how fast the sensation
    changes along the ladder's line (sensation per phase radian, at its
    coarser steps), a first measure of the sensory gain. ``center``: the
    sensation of the state it was measured at (the median of its repeats)."""

    sd: float
    repeat_sd: float
    ladder_sd: float
    lost_fraction: float
    slope: float = 0.0
    quantum: float = 0.0
    center: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def rounded(self) -> bool:
        """The outputs lie on a lattice (``quantum``) and repeats do not
        spread: the error is the rounding, the same at every repeat."""
        return self.quantum > 0 and self.repeat_sd < 0.5 * self.sd

    def metrics(self) -> dict:
        return {"naive.noise_estimate": float(self.sd),
                "naive.noise_repeat_sd": float(self.repeat_sd),
                "naive.noise_ladder_sd": float(self.ladder_sd),
                "naive.noise_quantum": float(self.quantum),
                "naive.lost_fraction": float(self.lost_fraction)}


def measure_noise(body, center: np.ndarray, *, repeats: int = 16,
                  line_rows: int = 16) -> SensoryNoise:
    """``SensoryNoise`` of ``body`` around ``center`` (phases), from ONE
    ``sense`` call of ``repeats + line_rows * len(ladder_steps())`` rows."""
    center = np.asarray(center, dtype=float).reshape(-1)
    for name, value in (("repeats", repeats), ("line_rows", line_rows)):
        if int(value) != value or value < 3:
            raise ValueError(f"{name} must be an integer >= 3, got {value}")
    sensed = np.asarray(body.sense(noise_rows(center, repeats, line_rows)), dtype=float)
    lost = float(np.mean(~np.all(np.isfinite(sensed), axis=1)))
    quantum = output_lattice(sensed)
    # A world that changed during the repeats: only its last world's count.
    repeated = sensed[last_world_start(sensed[:repeats], quantum):repeats]
    # The median absolute deviation reads heavy tails low, the clipped
    # variance does not: the larger, so that random noise of any shape is
    # not taken for rounding the repeats do not see.
    repeat_sd = max(repeat_spread(repeated), np.sqrt(clipped_variance(repeated, centred=True)[0]))
    lines = sensed[repeats:].reshape(len(ladder_steps()), line_rows, -1)
    ladder_sd = ladder_spread(lines)
    finite = sensed[np.isfinite(sensed)]
    roundoff = np.finfo(float).eps * (float(np.max(np.abs(finite))) if len(finite) else 0.0)
    sd = max(repeat_sd, ladder_sd, roundoff)
    pooled = random_noise(repeated, lines)
    if pooled is not None:          # one random noise: the sharper pooled estimate
        sd, repeat_sd, ladder_sd = max(pooled[0], roundoff), pooled[1], pooled[2]
    if quantum > 0 and repeat_sd < 0.5 * sd:
        # Rounding to a lattice errs uniformly within half a step: sd
        # quantum / sqrt(12) (second differences of rounded values see more).
        sd = max(repeat_sd, quantum / np.sqrt(12.0), roundoff)
    else:
        quantum = 0.0
    with np.errstate(all="ignore"):
        seen = np.nanmedian(np.where(np.isfinite(repeated), repeated, np.nan), 0)
    return SensoryNoise(sd, repeat_sd, ladder_sd, lost, line_slope(lines), quantum, seen)


# Accepted sensory errors a match may add up: an anchor is an earlier
# compensation, so poses drift along chains of them, each step by a random
# error within the accepted one (a chain's sum grows as the square root of
# its length; 256 errors cover the chains of the paper grid at noise 1e-8
# and float32). The tolerance only bounds how far a match may drift; which
# row matches is told by how far it stands out from the next nearest one
# (``Tolerances.ratio``), so a wide allowance does not join neighbours.
_CHAIN = 256.0
_CLOSE = 8.0


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


def measure_body(body, center: np.ndarray, params: NaiveParams, noise_measured=None):
    """Noise, then structure (at the step sized from the noise, probes
    averaged while the noise hides the rank). Returns ``(BodyStructure,
    sized NaiveParams)``; every row goes through ``body.sense``.
    ``noise_measured(center, noise)``, if given, is called between the two."""
    n_sensors = int(body.n_sensors)
    noise = measure_noise(body, center, repeats=params.noise_repeats,
                          line_rows=params.noise_repeats)
    if noise_measured is not None:
        noise_measured(center, noise)
    step = sized_fd_step(params, noise.sd, noise.slope, n_sensors)
    if noise.rounded:
        structure = rounded_structure(body, center, params)
        structure = replace(structure, noise=noise.sd, fd_step=max(step, params.fd_step),
                            repeat_noise=noise.repeat_sd, quantum=noise.quantum)
        return structure, sized_params(params, structure, n_sensors)
    if step <= params.fd_step:
        with getattr(body, "fresh", contextlib.nullcontext)():
            structure = measure_structure(body, center, fd_step=step,
                                          probes=params.structure_probes,
                                          radius=params.structure_radius,
                                          min_gap=params.rank_min_gap)
    else:
        structure = averaged_structure(body, center, params, noise, step)
    structure = replace(structure, noise=noise.sd, fd_step=step, repeat_noise=noise.repeat_sd)
    return structure, sized_params(params, structure, n_sensors)


def averaged_structure(body, center: np.ndarray, params: NaiveParams, noise: SensoryNoise,
                       step: float) -> BodyStructure:
    """The structure where measured noise sized the step: the rank probes'
    rows are sensed twice, then anew as often as before each round (their
    repeats pooled), while what the rank voted for leaves uncounted holds
    a direction that averaging up to ``structure_max_repeats`` sensings of
    each row (a budget of motor states) would count, beyond the rank or
    at the probes that count one less (``structure.more_could_count``): a
    faint pose direction is
    averaged out of the noise, one too faint for the budget is not chased.
    The noise is the probes' own, the spread of their repeats (rounding
    under noise that spreads is dithered by it and averages out too); where
    the repeats do not spread, averaging is not tried and the floor is the
    measured noise's (``averaged_sd``)."""
    # Two repeats show the spread; none shows where the repeats do not spread.
    sensed, repeats = None, 2 if noise.repeat_sd > 0 else 1
    while True:
        with getattr(body, "fresh", contextlib.nullcontext)():
            new = probe_rows(body, center, fd_step=step, probes=params.structure_probes,
                             radius=params.structure_radius, repeats=repeats)
        sensed = new if sensed is None else np.concatenate([sensed, new], axis=2)
        count = sensed.shape[2]
        row_sd = float(np.sqrt(repeat_variance(sensed) / count))
        structure, settled = probe_structure(sensed, step, params.rank_min_gap,
                                             row_sd or averaged_sd(noise, count),
                                             params.rank_noise_gap,
                                             count / params.structure_max_repeats)
        if settled or noise.repeat_sd == 0 or 2 * count > params.structure_max_repeats:
            return structure
        repeats = count


def averaged_sd(noise, repeats: int) -> float:
    """Per-receptor sd of a sensation averaged over ``repeats`` sensings: the
    random part (``repeat_sd``) shrinks, the part that repeats exactly
    (rounding, quantisation) stays."""
    # Repeats that spread about as much as the ladder sees: all of it random.
    fixed = 0.0 if noise.repeat_sd >= 0.5 * noise.sd else noise.sd ** 2 - noise.repeat_sd ** 2
    return float(np.sqrt(noise.repeat_sd ** 2 / repeats + fixed))


def sized_params(params: NaiveParams, structure: BodyStructure, n_sensors: int) -> NaiveParams:
    """``params`` with every exact-repeat tolerance raised to what the
    measured noise explains; a noiseless body keeps its parameters:

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
    """
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
    # The allowance stops at what the pose's weakest direction moves the
    # sensation over a walk's first knot interval (a drift the agent would
    # walk past anyway), never below _CLOSE accepted errors.
    drift = max(weakest * params.pov_initial_step / structure.gain, _CLOSE * sensory)
    match_tol = max(params.match_tol, min(_CHAIN * sensory, drift))
    return replace(
        params, fd_step=max(params.fd_step, structure.fd_step),
        lm_error_tol=max(params.lm_error_tol, sensory),
        pov_sample_tol=max(params.pov_sample_tol, motor),
        pov_predictor_tol=max(params.pov_predictor_tol, 2.0 * motor),
        match_tol=match_tol, match_separation=max(params.match_separation, 4.0 * match_tol))


def noise_step(params: NaiveParams, structure: BodyStructure, step: float = 0.0) -> float:
    """Twice the ``noise_confidence`` quantile of the part of a residual
    between two sensings that lies in the pose's ``rank`` directions
    (sensation units): over a state's ``rank``-th singular value, the
    Gauss-Newton step a search may keep there. With an ``AveragedStep``
    (a search's state sensed ``repeats`` times, its target at least once)
    the quantile itself, of that average's difference from one sensing."""
    if structure.noise <= 0 or structure.pose_rank < 1:
        return 0.0
    chi = chi2.ppf(params.noise_confidence, structure.pose_rank)
    if isinstance(step, AveragedStep):
        return float(structure.noise * np.sqrt((1.0 + 1.0 / step.repeats) * chi))
    return float(2.0 * structure.noise * np.sqrt(2.0 * chi))




def averaging_repeats(params: NaiveParams, structure: BodyStructure) -> int:
    """Sensings averaged per anchor and per search's end (``confirm``):
    ``accept_repeats`` where the noise is random (repeats spread about as
    much as the ladder sees), 1 where most of it repeats exactly (rounding,
    quantisation: averaging would not shrink it)."""
    if structure.noise <= 0 or structure.repeat_noise < 0.5 * structure.noise:
        return 1
    return int(params.accept_repeats)


def noise_residual(params: NaiveParams, structure: BodyStructure, n_sensors: int) -> float:
    """The ``noise_confidence`` quantile of the distance between two sensings
    of one motor state (sensation units): their difference over ``sqrt(2) sd``
    is chi with ``n_sensors`` degrees of freedom."""
    if structure.noise <= 0:
        return 0.0
    return float(structure.noise * np.sqrt(2.0 * chi2.ppf(params.noise_confidence, n_sensors)))


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
    averaged = averaged_step(params, structure, n_sensors, symmetric)
    # One sensing per row at the larger step would do: the symmetric step as
    # it was (measured at motor noise 1e-3 rad, paper seed 0: fewer POVs and
    # more wrong poses with the averaged step's tolerances; docs/noise.md).
    return averaged if averaged.repeats > 1 else symmetric


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
