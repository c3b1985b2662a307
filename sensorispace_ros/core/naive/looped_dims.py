"""Which of the agent's space dimensions loop: read from its equality sets.

An equality set is one change of the environment seen from many points of
view: pairs ``(i, j)`` of POVs, POV j sensing after the change what POV i
sensed before. Read as a map ``i -> j``, the same change can be repeated on
its own result: ``i -> j -> k -> ...``. The agent knows nothing of what the
change was; it only follows its own pairs.

The property measured is a loop closing: repeating one change returns to the
starting POV after L >= 2 repetitions. A translation can never do that (every
repetition moves the sensor by the same non-zero step, so it never comes
back); a turn by 2 pi / L can (a turn by pi swaps two POVs: i -> j -> i). So
a change with a closed chain moves the agent along a dimension that loops on
itself, and the agent's space has a looped dimension (the paper's
Discussion: "a rotation's dimension loops on itself"). Why this property and
not the others the Discussion names: it needs nothing but the pairs the agent
already has, no composition of changes (non-commutation needs two changes
chained in both orders, seen from the same POV) and no notion of an axis.

What it does not measure: how many looped dimensions there are. A closed
chain shows one loop at a time; the count reported is 1 when some change's
chain closes (``min_closing_sets`` of them, against a chance pairing error)
and 0 otherwise. The flat dimensions are the rest of ``space_dim`` (the
agent's own estimate from its metric, ``core.intrinsic_dimension``).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class LoopedDimensions:
    """``looped_dims`` and ``flat_dims`` of a space of ``space_dim``
    dimensions; ``closing_sets`` the equality sets with a closed chain,
    ``cycle_lengths`` how many closed chains of each length were seen."""

    looped_dims: int
    flat_dims: int
    closing_sets: tuple
    cycle_lengths: dict = field(default_factory=dict)

    def metrics(self) -> dict:
        return {"naive.looped_dims": self.looped_dims, "naive.flat_dims": self.flat_dims,
                "naive.closing_sets": len(self.closing_sets),
                "naive.closed_chains": int(sum(self.cycle_lengths.values())),
                "naive.shortest_closed_chain": min(self.cycle_lengths, default=0)}


def closed_chains(pairs: np.ndarray, max_length: int = 64) -> Counter:
    """Lengths of the closed chains of the map ``pairs[:, 0] -> pairs[:, 1]``
    (one equality set): each cycle counted once, L >= 2 (``i -> i`` is no change)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    step = dict(zip(pairs[:, 0].tolist(), pairs[:, 1].tolist()))
    lengths: Counter = Counter()
    done: set = set()
    for start in step:
        if start in done:
            continue
        chain, current = [start], step[start]
        while current in step and current not in chain and len(chain) < max_length:
            chain.append(current)
            current = step[current]
        done.update(chain)
        if current == start and len(chain) >= 2:
            lengths[len(chain)] += 1
    return lengths


def looped_dimensions(pairs, set_ids, space_dim: int, min_closing_sets: int = 2
                      ) -> LoopedDimensions:
    """Looped and flat dimensions of a space of ``space_dim`` dimensions, from
    the equality sets ``pairs`` ``(K, 2)`` / ``set_ids`` ``(K,)`` (module docstring)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    set_ids = np.asarray(set_ids).reshape(-1)
    if len(set_ids) != len(pairs):
        raise ValueError(f"set_ids: {len(set_ids)} ids for {len(pairs)} pairs")
    if int(space_dim) != space_dim or space_dim < 0:
        raise ValueError(f"space_dim must be an integer >= 0, got {space_dim!r}")
    if int(min_closing_sets) != min_closing_sets or min_closing_sets < 1:
        raise ValueError(f"min_closing_sets must be an integer >= 1, got {min_closing_sets!r}")
    lengths: Counter = Counter()
    closing = []
    order = np.argsort(set_ids, kind="stable")
    ids, starts = np.unique(set_ids[order], return_index=True)
    for set_id, rows in zip(ids, np.split(order, starts[1:])):
        found = closed_chains(pairs[rows])
        if found:
            closing.append(int(set_id))
            lengths.update(found)
    looped = int(len(closing) >= min_closing_sets and space_dim >= 1)
    return LoopedDimensions(looped, int(space_dim) - looped, tuple(closing),
                            dict(sorted(lengths.items())))
