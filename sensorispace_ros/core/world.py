"""The environment: a rigid object of point lights, its grid of positions, and
the schedules of environmental changes (paper Sec. 3.2, "Object displacements").

The environment state the paper calls ``e`` is the object's centre; lights
are stored as offsets from it. A *translation* moves the centre (and every
light) to a grid position; a *redistribution* draws new offsets around the
unmoved centre (a state change the agent must not be able to compensate).

With ``rotation_count`` K > 0 the object also turns: each displacement takes it
to a grid position and one of K orientations evenly spaced over a full turn
(``orientations``), the lights rotating about the object's centre. The paper
keeps rotations out (K = 0); its Discussion names them compensable
displacements too.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TRANSLATION = "translation"
REDISTRIBUTION = "redistribution"


def position_grid(half_width: float = 6.0, count: int = 62) -> np.ndarray:
    """Object positions, ``(count**2, 2)``, row-major in y then x.

    The paper's text says 64^2 positions; its 648 compensations and its
    Fig. 7a match ``linspace(-6, 6, 62)``, as its set-up says (62^2).
    """
    if count < 2:
        raise ValueError(f"grid count must be >= 2, got {count}")
    axis = np.linspace(-half_width, half_width, count)
    gx, gy = np.meshgrid(axis, axis)
    return np.stack([gx.ravel(), gy.ravel()], axis=-1)


def grid_spacing(half_width: float = 6.0, count: int = 62) -> float:
    return 2.0 * half_width / (count - 1)


def draw_light_offsets(rng: np.random.Generator, count: int = 10,
                       radius_min: float = 3.5, radius_max: float = 7.0) -> np.ndarray:
    """Light positions relative to the object's centre, uniform in an annulus.

    The paper only says "randomly distributed around the agent". Keeping
    lights out of the arm's reach (radius 3) keeps 1/d bounded; the annulus
    is a parameter.
    """
    if count < 1:
        raise ValueError(f"light count must be >= 1, got {count}")
    if not 0 <= radius_min < radius_max:
        raise ValueError(f"need 0 <= radius_min < radius_max, got {radius_min}, {radius_max}")
    # Uniform in area: radius ~ sqrt(uniform(r0^2, r1^2)).
    radius = np.sqrt(rng.uniform(radius_min ** 2, radius_max ** 2, size=count))
    angle = rng.uniform(-np.pi, np.pi, size=count)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)


@dataclass(frozen=True)
class EnvironmentEvent:
    """One change of the environment, as ground truth (never shown to the agent)."""

    index: int
    kind: str                    # TRANSLATION or REDISTRIBUTION
    center: np.ndarray           # object centre after the change, (2,)
    offsets: np.ndarray          # light offsets after the change, (L, 2)
    grid_index: int              # grid position of the centre (-1 if not on the grid)
    orientation: float = 0.0     # the object's rotation about its centre (rad)
    orientation_index: int = 0   # which of the schedule's orientations

    @property
    def lights(self) -> np.ndarray:
        if self.orientation == 0.0:
            return self.center + self.offsets
        return self.center + self.offsets @ rotation_matrix(self.orientation).T


def rotation_matrix(angle: float) -> np.ndarray:
    """The 2-D rotation by ``angle`` (rad), ``(2, 2)``."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def orientations(rotation_count: int) -> np.ndarray:
    """The object's orientations: ``rotation_count`` angles evenly spaced over a
    full turn from 0 (just 0 when the object does not turn, ``rotation_count`` 0)."""
    if int(rotation_count) != rotation_count or rotation_count < 0:
        raise ValueError(f"rotation_count must be an integer >= 0, got {rotation_count}")
    if rotation_count == 0:
        return np.zeros(1)
    return 2.0 * np.pi * np.arange(int(rotation_count)) / int(rotation_count)


def schedule(grid: np.ndarray, rng: np.random.Generator, initial_offsets: np.ndarray,
             redistribution_probability: float = 0.1, order: str = "random",
             light_kwargs: dict | None = None,
             rotation_count: int = 0,
             start_index: int | None = None) -> list[EnvironmentEvent]:
    """The sequence of environmental changes of one exploration.

    ``order="random"`` visits every grid position once in random order (the
    paper); ``order="tracking"`` visits them as a boustrophedon, so that each
    translation is to a neighbouring position. After each translation a
    redistribution follows with ``redistribution_probability``.
    ``rotation_count`` K > 0: every (grid position, orientation) pair is
    visited once (``order="tracking"``: every orientation at each position in
    turn, the positions as a boustrophedon).
    ``start_index``: the grid position the object starts at, which it is
    not moved to again in its starting orientation (its compensation is the
    start's own POV).
    """
    if not 0.0 <= redistribution_probability <= 1.0:
        raise ValueError("redistribution_probability must be in [0, 1], "
                         f"got {redistribution_probability}")
    light_kwargs = dict(light_kwargs or {})
    light_kwargs.setdefault("count", len(initial_offsets))
    angles = orientations(rotation_count)
    n_poses = len(grid) * len(angles)
    if order == "random":
        visit = rng.permutation(n_poses)
    elif order == "tracking":
        visit = (len(angles) * _boustrophedon(grid)[:, None] + np.arange(len(angles))).ravel()
    else:
        raise ValueError(f"schedule order must be 'random' or 'tracking', got {order!r}")
    if start_index is not None:
        visit = visit[visit != start_index * len(angles)]
    events: list[EnvironmentEvent] = []
    offsets = np.asarray(initial_offsets, dtype=float)
    for pose_index in visit:
        grid_index, turn = divmod(int(pose_index), len(angles))
        center, angle = grid[grid_index].copy(), float(angles[turn])
        events.append(EnvironmentEvent(len(events), TRANSLATION, center, offsets, grid_index,
                                       angle, turn))
        if rng.random() < redistribution_probability:
            offsets = draw_light_offsets(rng, **light_kwargs)
            events.append(EnvironmentEvent(len(events), REDISTRIBUTION, center, offsets,
                                           grid_index, angle, turn))
    return events


def _boustrophedon(grid: np.ndarray) -> np.ndarray:
    """Grid indices row by row, every other row reversed: each step is one cell."""
    ys = np.unique(grid[:, 1])
    order = []
    for row, y in enumerate(ys):
        idx = np.flatnonzero(grid[:, 1] == y)
        idx = idx[np.argsort(grid[idx, 0])]
        order.extend(idx[::-1] if row % 2 else idx)
    return np.asarray(order)
