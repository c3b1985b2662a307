"""Where the naive agent starts when the start it is given is degenerate.

Any start is a motor state; some see less than the body can: a straight
serial chain (every joint at 0) is singular, a pose that sees no light
senses nothing. The agent cannot tell from one measurement, so it asks its
body. ``structure.measure_structure`` at the start votes over probe states
around it; when they all agree (the usual case, the paper's start) nothing
more is sensed and the start is kept. Otherwise the rank at the start itself
is measured, together with the rank at ``SEARCH_FACTOR x probes`` motor
states drawn (seeded) over every joint's whole period, in one ``sense``
call, by the same rule as the probes (``point_ranks``). If some state
elsewhere has a higher rank than the start, the agent moves to the best
separated of the states of the highest rank and measures its body there again.
Nothing of the body is assumed: ranks are measured, states are phases.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.naive.structure import (BodyStructure, central_stencil, gap_rank,
                                                   jacobians_and_floor, noise_rank)
from sensorispace_ros.core.seeding import rng_for

# Motor states drawn elsewhere, per structure probe.
SEARCH_FACTOR = 4


@dataclass(frozen=True)
class StartChoice:
    """The agent's look at its start: the rank measured at the given start,
    the highest rank measured elsewhere, and whether it moved."""

    rank_at_start: int
    rank_elsewhere: int
    states_probed: int
    moved: bool

    def describe(self) -> str:
        if self.moved:
            return (f"the given start has pose rank {self.rank_at_start}, "
                    f"{self.rank_elsewhere} is measured elsewhere "
                    f"({self.states_probed} states probed): started at a state of rank "
                    f"{self.rank_elsewhere} instead")
        return (f"the given start has pose rank {self.rank_at_start}, no higher rank "
                f"measured elsewhere ({self.states_probed} states probed): start kept")


def point_ranks(body, states: np.ndarray, params,
                noise_sd: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rank and gap of the sensory Jacobian at each of ``states`` (phases), in
    one ``sense`` call; a state whose gap is below ``params.rank_min_gap``
    resolves nothing and has rank 0. ``noise_sd``: the measured noise, when
    the step was sized from it; the rank then counts the singular values
    clearly above it (``structure.noise_rank``), as the structure's probes do."""
    states = np.asarray(states, dtype=float)
    sensed = body.sense(central_stencil(states, params.fd_step))
    jac, floor = jacobians_and_floor(sensed, len(states), states.shape[1], params.fd_step,
                                     1, noise_sd)
    singular = np.linalg.svd(jac, compute_uv=False)
    if noise_sd is None:
        rank, gap = gap_rank(singular, floor)
        return np.where(gap >= params.rank_min_gap, rank, 0), gap
    rank, gap = noise_rank(singular, floor, params.rank_noise_gap)
    return np.where(gap >= params.rank_noise_gap, rank, 0), gap


def choose_start(body, start: np.ndarray, structure: BodyStructure, params, seed: int,
                 noise_sd: float | None = None) -> tuple[np.ndarray, StartChoice | None]:
    """``(start, choice)``: the given start when the structure's probes all
    agree on a rank above 0 (with ``noise_sd``: any rank above 0; choice
    None, nothing sensed), else the start this
    module's docstring describes; the caller measures a moved start anew.
    ``noise_sd``: as ``point_ranks``'."""
    # Under noise the probes were averaged until what they leave uncounted is
    # noise (``noise.averaged_structure``): a probe that disagrees sees its
    # weakest direction fainter than the floor, and ``point_ranks``' single
    # sensings elsewhere could only see less.
    if (structure.votes == structure.probes or noise_sd is not None) \
            and structure.pose_rank > 0:
        return start, None
    count = SEARCH_FACTOR * int(params.structure_probes)
    rng = rng_for(seed, "naive_start")
    elsewhere = rng.uniform(-np.pi, np.pi, (count, len(start)))
    ranks, gaps = point_ranks(body, np.vstack([start[None], elsewhere]), params, noise_sd)
    best = int(ranks[1:].max())
    if best <= ranks[0]:
        return start, StartChoice(int(ranks[0]), best, count, False)
    candidates = np.flatnonzero(ranks[1:] == best)
    chosen = elsewhere[candidates[np.argmax(gaps[1:][candidates])]].copy()
    return chosen, StartChoice(int(ranks[0]), best, count, True)
