"""The representation node's Hausdorff matrix, grown while the POVs arrive
(``core.hausdorff.GrowingHausdorffMatrix``, in one worker thread): at
/agent/done only the last POVs' distances are left to compute. The same bits
as computing it at the end; without numba, or if a POV message did not hold
whole POVs, it is given up and computed at the end.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from sensorispace_ros.offline.pov_assembly import assemble_points_of_view


class GrowingHausdorff:
    """What ``RepresentationNode`` does to grow its Hausdorff matrix."""

    def init_hausdorff(self) -> None:
        # POV ids in the order added, and the one thread that adds them (in
        # order); the matrix is None until the first POV.
        self.hausdorff = None
        self.hausdorff_ids: list[int] = []
        self.hausdorff_worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="hausdorff")
        self.hausdorff_failed = False

    def grow_hausdorff(self, table: np.ndarray) -> None:
        """Queue the distances of this table's POVs to those held (see the module
        docstring); gives the growing matrix up for one computed at the end when
        the table does not hold whole POVs or numba is missing."""
        from sensorispace_ros.core.hausdorff import GrowingHausdorffMatrix, numba_available
        if self.hausdorff_failed:
            return
        try:
            ids, povs = assemble_points_of_view([table], self.description.n_motors)
        except ValueError as exc:
            self.give_up_hausdorff(f"a message holds part of a POV ({exc})")
            return
        if self.hausdorff is None:
            if not numba_available():
                self.give_up_hausdorff("numba is not installed")
                return
            self.hausdorff = GrowingHausdorffMatrix(povs.shape[1], povs.shape[2])
        elif povs.shape[1:] != (self.hausdorff.n_samples, self.hausdorff.n_motors):
            self.give_up_hausdorff(f"POVs of {povs.shape[1]} samples after POVs of "
                                   f"{self.hausdorff.n_samples}")
            return
        try:
            self.hausdorff_worker.submit(self._add_to_hausdorff,
                                         self.description.to_radians(povs))
        except RuntimeError:                # after the build took the matrix (shut down)
            self.give_up_hausdorff("a POV arrived after the representation was started")
            return
        self.hausdorff_ids.extend(ids.tolist())

    def _add_to_hausdorff(self, povs: np.ndarray) -> None:
        if self.hausdorff_failed or self.closing:
            return
        try:
            self.hausdorff.add(povs)
        except Exception as exc:            # computed at the end instead
            self.give_up_hausdorff(f"{type(exc).__name__}: {exc}")

    def give_up_hausdorff(self, reason: str, expected: bool = False) -> None:
        """Compute the matrix at the end instead, for ``reason``: a warning, or,
        where ``expected`` (the POVs moved at the end of the run), said once."""
        if expected and self.hausdorff_failed:
            return
        self.hausdorff_failed = True
        log = self.get_logger().info if expected else self.get_logger().warning
        log(f"the Hausdorff matrix will be computed at the end: {reason}")

    def grown_hausdorff(self, ids: np.ndarray) -> np.ndarray | None:
        """The grown matrix for POVs ``ids`` (sorted), once every add is done;
        None if it was given up or does not hold exactly those POVs."""
        self.hausdorff_worker.shutdown(wait=True)
        if self.hausdorff_failed or self.hausdorff is None:
            return None
        added = np.asarray(self.hausdorff_ids, dtype=np.int64)
        if len(added) != self.hausdorff.count or not np.array_equal(np.sort(added), ids):
            self.get_logger().warning("the grown Hausdorff matrix does not hold the POVs "
                                      "received; computing it at the end")
            return None
        return self.hausdorff.matrix(np.argsort(added, kind="stable"))
