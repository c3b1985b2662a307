"""Which known POV a search's end lies on, in motor space (``NaiveAgent``
inherits it through ``SearchAndSample``).

Where noise sized the tolerances and the POVs are loops, sensations alone
tell poses apart poorly: two ends on one pose sense apart by more than two
sensings differ along the strong pose directions, and a known POV one grid
step from the end may sense like its target within the match tolerance
(which allows for errors that add up along chains of compensations). Motor
space tells them apart, in shares of the POVs' measured separation
(``PovStore.separation``, the median distance from a POV to its nearest
neighbour's loop):

* nearer a known POV's loop than ``ON_LOOP`` (a quarter: half way to half
  way between neighbours), an end is that POV (``_walked_pose``), and a POV
  the sensations name keeps only such an end (``_on_known_loop``);
* from ``APART`` on, it is a pose no known POV holds: a new POV;
* in between it lies off the lattice of positions the POVs found so far
  share (its anchor rested off it, or the search stopped short): neither
  that POV nor a new one (``_between_loops``). Taken for the POV it would
  pair two POVs a fraction of a step apart in the equality sets; walked as
  a new one it would breed a second lattice, offset from the first.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.neighbours import loop_distances

ON_LOOP = 0.25
APART = 0.6


class KnownLoops:
    """Mixin: needs the agent's ``_noisy``, ``structure``, ``params`` and ``_store``."""

    ends_between_loops = 0      # search ends refused by ``_between_loops``

    def _loops_tell_poses(self) -> bool:
        """Noise sized the tolerances, the POVs are loops and enough of them
        are known to measure their separation (``pose_precision_povs``)."""
        return bool(self._noisy and self.structure.pov_dim == 1 and
                    self._store.count >= self.params.pose_precision_povs)

    def _walked_pose(self, motor_state: np.ndarray) -> int:
        """Where loops tell poses (``_loops_tell_poses``): the known POV whose
        loop passes within ``ON_LOOP`` of their separation of ``motor_state``,
        -1 if none. Two ends on one pose are one POV, not two (each would
        breed its own frontier rows, one position twice)."""
        if not self._loops_tell_poses():
            return -1
        pov, distance = self._nearest_loop(motor_state, ON_LOOP)
        return pov if distance <= ON_LOOP * self._store.separation() else -1

    def _on_known_loop(self, motor_state: np.ndarray, pov: int) -> bool:
        """Whether ``motor_state`` may be POV ``pov``, which senses like it:
        always where loops do not tell poses, else only within ``ON_LOOP`` of
        the POVs' separation of its loop."""
        if not self._loops_tell_poses():
            return True
        distance = loop_distances(motor_state, self._store.samples[[pov]])[0]
        return bool(distance <= ON_LOOP * self._store.separation())

    def _between_loops(self, motor_state: np.ndarray) -> bool:
        """Where loops tell poses: whether the nearest known loop lies between
        ``ON_LOOP`` and ``APART`` of the POVs' separation from ``motor_state``."""
        if not self._loops_tell_poses():
            return False
        separation = self._store.separation()
        _, distance = self._nearest_loop(motor_state, APART)
        return bool(ON_LOOP * separation < distance < APART * separation)

    def _nearest_loop(self, motor_state: np.ndarray, share: float):
        """``(POV, distance)`` of the known loop nearest ``motor_state`` among
        those that may pass within ``share`` of the separation; ``(-1, inf)``
        if none may."""
        limit = share * self._store.separation()
        # A point within ``limit`` of a chord lies within ``limit`` plus half
        # the chord of one of its ends: only POVs with a sample that near.
        candidates = self._store.near(motor_state, limit + 0.5 * self._longest_chord())
        if not len(candidates):
            return -1, np.inf
        distance = loop_distances(motor_state, self._store.samples[candidates])
        nearest = int(np.argmin(distance))
        return int(candidates[nearest]), float(distance[nearest])

    def _longest_chord(self) -> float:
        """The longest step between consecutive samples of a known POV's loop
        (torus of phases), measured for the POVs appended since last asked."""
        done, longest = getattr(self, "_chords", (0, 0.0))
        if self._store.count > done:
            loops = self._store.samples[done:]
            step = (np.roll(loops, -1, axis=1) - loops + np.pi) % (2.0 * np.pi) - np.pi
            longest = max(longest, float(np.sqrt(np.max(np.sum(step * step, axis=2)))))
            self._chords = (self._store.count, longest)
        return longest
