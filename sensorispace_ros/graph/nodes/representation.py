"""Representation node: points of view + equality sets -> embeddings.

Subscribes only to ``/agent/*`` and to the body description
(``/body/description``), which fixes the POVs' motor columns (``m0..m{N-1}``)
and their unit: POV messages that come before it wait for it, and motor
values are turned into angles (``BodyDescription.to_radians``, a period to
2 pi; the same bits for radians) before the Hausdorff metric, whose wrap is
2 pi. The arrays written keep the body's own unit. Collects the points of
view and the equality rows; a re-sent message is not counted twice and the
first copy wins: POV ids it already holds and a second ``/agent/compensations`` message
for one change (frame id) are ignored (a restarted agent re-publishes the
reaction of the change it died in); once ``/agent/done`` has arrived and
the totals match, runs ``offline.representation.build_representation`` in a worker
thread, publishes ``/representation/embedding`` for every dimension and
regularisation iteration, and writes its arrays to
``<run directory>/representation.npz`` (``protocol.run_directory``: the
stamp of ``/agent/done`` names it); with fewer than 4 POVs none is built and
the file holds the agent's outputs and the ``reason``. Ground truth is joined
later, by the evaluator, never here. It exits then, unless
``graph.exit_when_done`` is false.

The 2-D and 3-D chains run in two worker processes of a forkserver pool
(``offline.chain_pool.start_chain_pool``; a process with DDS threads must not fork),
started with the node so that their start-up overlaps the exploration, and
stopped with it (``destroy_node``), on SIGTERM too.

The Hausdorff matrix grows while the POVs arrive
(``graph.nodes.growing_hausdorff``).
"""
from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np

from sensorispace_ros import contracts, messages
from sensorispace_ros.graph.framework import GraphNode, run_node
from sensorispace_ros.graph.nodes.growing_hausdorff import GrowingHausdorff
from sensorispace_ros.protocol import EQUALITY_ROW_KINDS, RESULT_FILE, run_directory
from sensorispace_ros.offline.pov_assembly import (  # noqa: F401  (re-exported)
    MIN_POVS, assemble_points_of_view, embedding_arrays, equality_pairs, net_equality_rows)

CHAIN_POOL_DELAY_S = 3.0


class RepresentationNode(GrowingHausdorff, GraphNode):

    def __init__(self, **kwargs):
        super().__init__("representation", **kwargs)
        self.columns = {topic: self.columns_of(topic) for topic in (
            "/agent/compensations", "/agent/done", "/representation/embedding")}
        self.embedding_pub = contracts.create_publisher(self, "/representation/embedding")
        self.subscribe_description(lambda description: self.maybe_start())
        contracts.create_subscription(self, "/agent/points_of_view", self.when_described(
            "/agent/points_of_view", self.on_points_of_view))
        contracts.create_subscription(self, "/agent/compensations", self.on_compensations)
        contracts.create_subscription(self, "/agent/done", self.on_done)
        self.pov_tables: dict[str, np.ndarray] = {}
        self.pov_ids: set[int] = set()
        self.moved_tables: dict[str, np.ndarray] = {}   # end/<k>: POVs moved at the end
        self.moved_ids: set[int] = set()
        self.row_tables: dict[str, np.ndarray] = {}
        self.duplicates = 0             # messages (or POVs) already held, ignored
        self.totals: dict | None = None
        self.worker: threading.Thread | None = None
        self.result: dict | None = None
        self.finished = False
        self.exit_code = 0
        self.results_dir: Path | None = None     # the run directory, from /agent/done
        self.chain_pool = None
        self.closing = False
        self._start_pool_now = threading.Event()
        self.chain_pool_starter = threading.Thread(target=self._start_chain_pool,
                                                   name="chain-pool", daemon=True)
        self.chain_pool_starter.start()
        self.init_hausdorff()

    def _start_chain_pool(self) -> None:
        from sensorispace_ros.offline import chain_pool
        from sensorispace_ros.core.hausdorff import hausdorff_matrix

        # After the other nodes' start-up (or at once when the run is over, or
        # the node closing): the forkserver and its two workers import numpy,
        # scipy, scikit-learn and numba (~2 s of CPU), which slowed the graph's
        # start on two cores; the exploration leaves CPU to spare.
        self._start_pool_now.wait(CHAIN_POOL_DELAY_S)
        if self.closing:
            return
        started = time.monotonic()
        # Loads numba's cached Hausdorff kernels now rather than after
        # /agent/done (import and first call: ~0.5 s); any shape loads the same.
        hausdorff_matrix(np.linspace(0.0, 1.0, 6 * 10 * 4).reshape(6, 10, 4))
        try:
            pool = chain_pool.start_chain_pool()
        except Exception as exc:            # no pool: the chains run in turn here
            self.get_logger().warning(f"no worker pool for the 2-D/3-D chains, they will run "
                                      f"in turn: {type(exc).__name__}: {exc}")
            return
        if self.closing:                    # destroyed while the pool was starting
            chain_pool.stop_chain_pool(pool)
            return
        self.chain_pool = pool
        self.get_logger().info(f"chain pool ready in {time.monotonic() - started:.1f} s, "
                               f"worker pids {chain_pool.chain_pool_pids(pool)}")

    def _decode(self, topic: str, msg, kinds=("change",)):
        decoded = self.decode(topic, msg, kinds, as_table=True)
        return None if decoded is None else decoded[1]

    def on_points_of_view(self, msg) -> None:
        decoded = self.decode("/agent/points_of_view", msg, ("change", "end"), as_table=True)
        if decoded is None or not len(decoded[1]):
            return
        (kind, _), table = decoded
        if kind == "end":
            self.on_moved_povs(msg.header.frame_id, table)
            return
        held = np.isin(table["pov"], list(self.pov_ids))
        if held.any():
            self.duplicates += 1
            table = table[~held]
            if not len(table):
                return
        key = msg.header.frame_id
        if key in self.pov_tables:          # new POVs under a frame id already seen
            key = f"{key}#{len(self.pov_tables)}"
        self.pov_tables[key] = table
        self.pov_ids.update(int(pov) for pov in np.unique(table["pov"]))
        self.grow_hausdorff(table)
        self.maybe_start()

    def on_moved_povs(self, frame_id: str, table: np.ndarray) -> None:
        """POVs the agent moved at the end of its run: their samples replace
        those held (``assemble_points_of_view``'s ``moved``)."""
        if frame_id in self.moved_tables:
            self.duplicates += 1
            return
        self.moved_tables[frame_id] = table
        self.moved_ids.update(int(pov) for pov in np.unique(table["pov"]))
        self.give_up_hausdorff("points of view moved at the end of the run", expected=True)
        self.maybe_start()

    def on_compensations(self, msg) -> None:
        table = self._decode("/agent/compensations", msg, kinds=EQUALITY_ROW_KINDS)
        if table is None or not len(table):
            return
        if msg.header.frame_id in self.row_tables:
            self.duplicates += 1
            return
        self.row_tables[msg.header.frame_id] = table
        self.maybe_start()

    def on_done(self, msg) -> None:
        table = self._decode("/agent/done", msg, kinds=("end",))
        if table is None:
            return
        if len(table) != 1:
            self.drop("/agent/done", f"{len(table)} rows")
            return
        self.totals = {name: int(table[name][0]) for name in table.dtype.names}
        self.results_dir = run_directory(self.graph["results_dir"],
                                         messages.stamp_ns(msg.header))
        self._start_pool_now.set()
        self.maybe_start()

    def maybe_start(self) -> None:
        if self.totals is None or self.worker is not None or self.description is None:
            return
        held = (len(self.pov_ids), sum(len(t) for t in self.row_tables.values()),
                len(self.moved_ids))
        if held != (self.totals["points_of_view"], self.totals["compensation_rows"],
                    self.totals.get("moved_povs", 0)):
            return                          # still in flight on another topic
        self.worker = threading.Thread(target=self.build, name="representation", daemon=True)
        self.worker.start()

    def build(self) -> None:
        try:
            ids, povs = assemble_points_of_view(list(self.pov_tables.values()),
                                                self.description.n_motors,
                                                moved=list(self.moved_tables.values()))
            rows = net_equality_rows(self.row_tables,
                                     messages.record_dtype(self.columns["/agent/compensations"]))
            pairs, set_ids = equality_pairs(ids, rows)
            # Same array names as evaluation.run_files.run_arrays, so evaluation code is shared.
            arrays = {"pov_ids": ids, "povs": povs, "pairs": pairs, "set_ids": set_ids,
                      **{f"agent_{key}": np.int64(value) for key, value in self.totals.items()}}
            if len(ids) < MIN_POVS:
                arrays["reason"] = np.asarray(f"{len(ids)} points of view: a representation "
                                              f"needs at least {MIN_POVS}")
            else:
                arrays.update(self.representation_arrays(ids, povs, pairs, set_ids, len(rows)))
            self.results_dir.mkdir(parents=True, exist_ok=True)
            np.savez(self.results_dir / RESULT_FILE, **arrays)
            self.result = arrays
            reason = f" ({arrays['reason']}: none built)" if "reason" in arrays else ""
            self.get_logger().info(f"representation written to "
                                   f"{self.results_dir / RESULT_FILE}{reason}")
        except Exception as exc:
            if self.closing:                # stopped mid-build: the pool was ended under it
                return
            self.get_logger().error(f"representation failed: {type(exc).__name__}: {exc}")
            self.exit_code = 1
            self.finished = True
            raise
        self.finished = bool(self.graph["exit_when_done"])

    def representation_arrays(self, ids, povs, pairs, set_ids, n_rows: int) -> dict:
        """Build the representation, publish its embeddings; its arrays."""
        self.get_logger().info(f"building the representation of {len(ids)} points of view, "
                               f"{n_rows} equality rows")
        distance = self.grown_hausdorff(ids)
        self.chain_pool_starter.join()
        representation = self._build_representation(
            self.description.to_radians(povs), pairs, set_ids, distance)
        for dim in sorted(representation.before):
            stages = [representation.before[dim], *representation.iterations[dim]]
            for k, embedding in enumerate(stages):
                self.publish_embedding(ids, embedding, f"{dim}/iteration/{k}")
        return {"hausdorff": representation.distance, **embedding_arrays(representation),
                "timings_s_json": np.asarray(json.dumps(representation.timings_s))}

    def _build_representation(self, angles: np.ndarray, pairs: np.ndarray,
                              set_ids: np.ndarray, distance: np.ndarray | None = None):
        """``offline.representation.build_representation`` of the POVs as angles
        (rad, period 2 pi)."""
        from concurrent.futures.process import BrokenProcessPool

        from sensorispace_ros.offline.representation import build_representation
        if self.chain_pool is not None:
            try:
                return build_representation(angles, pairs, set_ids, self.cfg,
                                            self.cfg["seed"], executor=self.chain_pool,
                                            distance=distance)
            except BrokenProcessPool as exc:
                if self.closing:
                    raise
                self.get_logger().warning(f"the chain pool broke ({exc}); "
                                          "building again with the chains in turn")
        return build_representation(angles, pairs, set_ids, self.cfg, self.cfg["seed"],
                                    processes=1, distance=distance)

    def destroy_node(self):
        """Stops the chain pool first: none of its workers outlives the node."""
        from sensorispace_ros.offline import chain_pool
        self.closing = True
        self._start_pool_now.set()
        self.hausdorff_worker.shutdown(wait=True, cancel_futures=True)
        self.chain_pool_starter.join()
        pool, self.chain_pool = self.chain_pool, None
        if pool is not None:
            chain_pool.stop_chain_pool(pool)
        return super().destroy_node()

    def publish_embedding(self, ids: np.ndarray, embedding: np.ndarray, frame_id: str) -> None:
        embedding = np.asarray(embedding, dtype=float)
        xyz = np.zeros((len(ids), 3))
        xyz[:, :embedding.shape[1]] = embedding
        self.embedding_pub.publish(messages.table_to_cloud(
            {"pov": ids, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]},
            self.columns["/representation/embedding"],
            messages.make_header(frame_id, self.get_clock().now().nanoseconds)))


def main(args=None) -> int:
    return run_node(RepresentationNode, "representation", args)


if __name__ == "__main__":
    raise SystemExit(main())
