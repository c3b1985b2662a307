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
* in between it may lie off the lattice of positions the POVs found so far
  share (its anchor rested off it, or the search stopped short): neither
  that POV nor a new one (refused by ``_placed_end``). Taken for the POV it would
  pair two POVs a fraction of a step apart in the equality sets; walked as
  a new one it would breed a second lattice, offset from the first.

Motor distances mean different pose distances from place to place on an
arm, so where the agent measured the manifold the loops sweep
(``loop_manifold``) that manifold decides past ``HALF`` of the separation:
an end on it lies nearer a new position of the lattice than a known one
and is a new POV; an end off it changed a pose component no displacement
changes, and is refused however far it lies.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.motor_loops import loop_chords
from sensorispace_ros.core.naive import loop_manifold
from sensorispace_ros.core.naive.neighbours import loop_distances

ON_LOOP = 0.25
HALF = 0.5
APART = 0.6
# An end lies off the loops' manifold beyond this many times the POVs' own
# median offset from it (measured at up to ``CALIBRATION_POVS`` of them).
OFF_FACTOR = 8.0
CALIBRATION_POVS = 32


class KnownLoops:
    """Mixin: needs the agent's ``_noisy``, ``structure``, ``params`` and ``_store``."""

    ends_between_loops = 0      # search ends refused by ``_between_loops``
    ends_off_manifold = 0       # of them, those refused off the loops' manifold

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

    def _placed_end(self, motor_state: np.ndarray) -> tuple[int, bool]:
        """``(known POV, refused)`` of a search's end at ``motor_state``, from
        one query of the known loops: the POV whose loop lies within
        ``ON_LOOP`` of the POVs' separation (as ``_walked_pose``), else -1
        and whether it is refused. Where the loops' manifold is measured it
        is refused nearer than ``HALF`` to a known loop or off the manifold
        (``_off_manifold``); where it is not, nearer than ``APART``."""
        if not self._loops_tell_poses():
            return -1, False
        separation = self._store.separation()
        pov, distance = self._nearest_loop(motor_state, APART)
        if distance <= ON_LOOP * separation:
            return pov, False
        codim, limit = self._manifold()
        if limit is None:
            return -1, bool(distance < APART * separation)
        if distance < HALF * separation:
            return -1, True
        off = self._off_manifold(motor_state, codim, limit)
        self.ends_off_manifold += int(off)
        return -1, off

    def _off_manifold(self, motor_state: np.ndarray, codim: int, limit: float) -> bool:
        """Whether ``motor_state`` lies off the known loops' manifold (of
        ``codim``) by more than ``limit`` (``_manifold``'s), that measured a
        separation from the nearest loop: farther, the fitted plane is
        extrapolated and the manifold's bend grows with the square of the
        distance, and so does the limit."""
        offset, reach = loop_manifold.normal_offset(motor_state, self._store.samples, codim)
        return bool(offset > limit * max(1.0, (reach / self._store.separation()) ** 2))

    def _manifold(self):
        """``(codimension, offset limit)`` of the known loops' manifold: the
        limit ``OFF_FACTOR`` times the POVs' own median offset; ``(0, None)``
        where the loops leave no motor direction out or are too few to fit
        one. Measured again when the POVs have grown by an eighth."""
        count = self._store.count
        cached = getattr(self, "_manifold_cache", (0, 0, None))
        if count < cached[0] * 9 / 8:
            return cached[1:]
        if count <= 2 * loop_manifold.K_LOOPS:
            return 0, None
        probes = np.unique(np.linspace(0, count - 1, min(count, CALIBRATION_POVS)).astype(int))
        codim, own = loop_manifold.measure(self._store.samples, probes)
        limit = None if own is None else OFF_FACTOR * float(np.median(own))
        self._manifold_cache = (count, codim, limit)
        return codim, limit

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
            step = loop_chords(loops)
            longest = max(longest, float(np.sqrt(np.max(np.sum(step * step, axis=2)))))
            self._chords = (self._store.count, longest)
        return longest
