"""When exploring stops paying, for an agent whose every probe is a move.

On a clock, the agent would explore until the world's schedule runs out,
and its late POVs cost the most: a reaction finds one less and less often
as the POVs it knows fill its reach. ``ExplorationYield`` watches what the
agent spends against what it finds, from its own counts only (motor states
probed, POVs known): once the last ``window`` POVs cost more than ``ratio``
times the mean cost of a POV so far (the motor states since the POV
``window`` before, a drought included), exploring has stopped paying and
the agent turns to simulation 2 at the next change
(``clocked_run.drive``). The rule reads nothing about the world; ``ratio``
0 never stops.
"""
from __future__ import annotations

__all__ = ["ExplorationYield"]


class ExplorationYield:
    """Motor states probed when each POV was first known, and the stop rule."""

    def __init__(self, ratio: float, window: int):
        if not ratio >= 0.0:
            raise ValueError(f"ratio: must be >= 0, got {ratio!r}")
        if int(window) < 1:
            raise ValueError(f"window: must be an integer >= 1, got {window!r}")
        self.ratio, self.window = float(ratio), int(window)
        self.costs: list[int] = []       # motor states probed when the k-th POV was known
        self.stopped_at: int | None = None

    def explored(self, queries: int, povs: int) -> bool:
        """Note ``queries`` motor states probed and ``povs`` POVs known now;
        True once the last ``window`` POVs cost more than ``ratio`` times
        the mean (and from then on). Not before ``2 * window`` POVs: the
        start's cost weighs on the mean of the first few."""
        if self.stopped_at is not None:
            return True
        self.costs.extend([int(queries)] * (int(povs) - len(self.costs)))
        if self.ratio <= 0 or povs < 2 * self.window:
            return False
        recent = (queries - self.costs[povs - self.window - 1]) / self.window
        if recent > self.ratio * queries / povs:
            self.stopped_at = int(queries)
            return True
        return False
