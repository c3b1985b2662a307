"""What a reaction of the agent on a clock senses again, once done, to tell
whether the world changed while it worked.

A reaction's sentinels (``ClockedAgent.sense_sentinels``) are its resting
state and a *lookout* that senses something (``brightest``): where the
resting state and every candidate sense nothing, known POVs are sensed in
turn for one (``_lookout_among_known``). A change the resting state does
not see (it senses nothing before and after) shows in the *witnesses*: the
swept POVs that sensed most in the reaction's sweep
(``ClockedAgent._sweep_known`` holds them) and, from what it sensed since
the change, the states that sensed most in each half of the reaction.
``check_reaction`` senses them with the resting states in one call: one
round trip in the graph.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive import change_detection

WITNESSES = 4        # swept POVs sensed again after a reaction
LOOKOUT_TRIES = 16   # known POVs sensed for a lookout when the sentinels sense nothing


def lit(sensed: np.ndarray) -> np.ndarray:
    """How much each row of ``sensed`` ``(B, S)`` senses: its norm, -1 for a
    row with a lost value."""
    return np.where(np.all(np.isfinite(sensed), axis=1), np.linalg.norm(sensed, axis=1), -1.0)


def brightest(states: np.ndarray, sensed: np.ndarray, noise_sd: float):
    """``(state, sensation)`` of the state that sensed most, if its sensation
    tells from nothing (``senses_nothing``); else None: a sentinel that
    senses nothing sees a change only when light comes into its view."""
    if not len(states):
        return None
    amount = lit(sensed)
    best = int(np.argmax(amount))
    if amount[best] < 0 or senses_nothing(noise_sd, sensed[best]):
        return None
    return states[best].copy(), sensed[best].copy()


def senses_nothing(noise_sd: float, sensed: np.ndarray) -> bool:
    """Whether ``sensed`` does not tell from nothing."""
    return not change_detection.differs(noise_sd, np.zeros_like(sensed), sensed)


class Witnesses:
    """Mixin of ``ClockedAgent``: needs its ``_body``, ``n_motors``,
    ``noise_sd``, ``sense_again``, ``_to_body``, ``_store`` and ``_witnesses``
    (the sweep's, or None)."""

    def _lookout_among_known(self):
        """A lookout for a reaction whose resting state and lookout candidates
        all sense nothing (a change there would pass unseen until the
        reaction's end): the next ``LOOKOUT_TRIES`` known POVs in turn, sensed
        in one call; the one that senses most (``brightest``), or None."""
        count = self._store.count
        if count == 0:
            return None
        start = getattr(self, "_lookout_cursor", 0) % count
        chosen = (start + np.arange(min(LOOKOUT_TRIES, count))) % count
        self._lookout_cursor = start + len(chosen)
        states = self._to_body(self._store.samples[chosen, 0]).reshape(-1, self.n_motors)
        return brightest(states, self.sense_again(states), self.noise_sd)

    def witnesses_moved(self) -> bool:
        """Sense again the witnesses of this reaction (``_witness_states``):
        did any move? A change the resting state does not see (it sees
        nothing before and after) shows there."""
        return self.check_reaction(np.zeros((0, self.n_motors)))[1]

    def check_reaction(self, rests) -> tuple[np.ndarray, bool]:
        """Sense the states ``rests`` (body units) afresh and, in the same
        call, the witnesses of this reaction. Returns the sensations of
        ``rests`` and whether a witness moved."""
        rests = np.asarray(rests, dtype=float).reshape(-1, self.n_motors)
        states, held = self._witness_states()
        if not len(rests) + len(states):
            return np.zeros((0, self._body.n_sensors)), False
        again = self.sense_again(np.vstack([rests, self._to_body(states)]))
        moved = any(change_detection.differs(self.noise_sd, a, b)
                    for a, b in zip(held, again[len(rests):]))
        return again[:len(rests)], moved

    def _witness_states(self):
        """The witnesses of this reaction, ``(states, sensations held)``: its
        swept POVs that sensed most and, from what it sensed since the
        change, the states that sensed most in each half of the reaction."""
        states, held = self._memory_witnesses()
        if self._witnesses is not None:
            states = np.vstack([self._witnesses[0], states])
            held = np.vstack([self._witnesses[1], held])
        return states, held

    def _memory_witnesses(self):
        """``WITNESSES`` states sensed since the change that sensed most, half
        from each half of the reaction (none without ``remember_sensations``)."""
        memory = getattr(self._body, "_sensed", None)
        empty = np.zeros((0, self.n_motors)), np.zeros((0, self._body.n_sensors))
        if memory is None or memory.count == 0:
            return empty
        states = memory._motor_states[:memory.count]
        sensed = memory._sensations[:memory.count]
        amount = lit(sensed)
        half = memory.count // 2
        chosen = []
        for part in (np.arange(half), np.arange(half, memory.count)):
            chosen.extend(part[np.argsort(-amount[part], kind="stable")[:WITNESSES // 2]])
        chosen = np.asarray(chosen, dtype=int)
        chosen = chosen[amount[chosen] > 0]
        return states[chosen].copy(), sensed[chosen].copy()
