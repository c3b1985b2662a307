"""Graph probe round trip vs a bare rclpy ping-pong of the same message sizes.

Four server processes in one private domain (localhost discovery):
  * the real body node (``python -m sensorispace_ros.graph.nodes.body``), which
    decodes each /body/motor_command, simulates the arm and retina, and
    publishes /body/sensation, /body/sensor_pose and /body/joint_states;
  * ``bench/rclpy_echo.py``, which answers a ``rows x 4`` float64
    PointCloud2 with a prebuilt ``rows x 6`` one (one publication, no work),
    spun by rclpy's stock SingleThreadedExecutor: the bare baseline;
  * ``bench/rclpy_echo.py --lean``: the same with serialized bytes, spun by
    the graph's executor (``graph.framework.make_executor``, as the body
    node): the floor;
  * ``bench/rclpy_echo.py --simulate``: decode + simulate + pack, one
    publication (diagnostic: where the graph's excess goes), reporting its
    own simulation time per answer.
The client (this process, one node) probes the body exactly as the agent
node does - ``graph.body_over_topics.BodyOverTopics`` with the contract's
publisher, commands and answers as serialized bytes (``messages.CloudCdrPacker``,
``CloudCdrReader``), waiting in the graph's executor - and pings
the echoes with prebuilt messages, waiting the same way: the client's side is
the same for every kind. All are measured in the same run, interleaved in
rounds so load changes hit them alike. Servers are stopped by PID.

Ratios (medians): ``ratio_median`` = graph / bare, the raw ratio (the
target: <= 1.3): the bare echo does no work at all, so it includes the body's
simulation of the rows (compiled: ~2 us for 1 row, ~0.2 ms for 649 rows x 10
lights x 6 receptors). ``ratio_median_vs_lean_bare`` = graph / the lean echo.
``ratio_median_net_of_simulation`` = (graph - simulation) / bare, with the
simulation time measured inside the sim echo (a server process answering
probes, as the body node); ``ratio_median_net_of_compute`` the same with the
simulation timed in this process's loop (hot caches: lower for 1 row). The
net ratios are the graph's messaging overhead over bare rclpy.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from bench.child import child_environment, load  # noqa: E402


def _stop(proc: subprocess.Popen, grace_s: float = 5.0) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()


def measure(config: str | Path = "config/smoke.yaml", batch_rows: int = 649,
            rounds: int = 10, per_round: dict | None = None, seed: int = 0,
            log_dir: str | Path | None = None) -> dict:
    """Median / mean round trip per probe (ms) for the graph and the bare
    ping-pong, single row and ``batch_rows`` rows; ratio graph / bare."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import PointCloud2

    from bench import rclpy_echo
    from sensorispace_ros import config as config_mod
    from sensorispace_ros import contracts, messages
    from sensorispace_ros.graph import dds_environment
    from sensorispace_ros.graph.framework import build_world, frame, make_executor
    from sensorispace_ros.graph.body_over_topics import BodyOverTopics

    per_round = per_round or {1: 100, batch_rows: 20}
    config = Path(config)
    if not config.is_absolute():
        config = HERE.parent / config
    cfg = config_mod.load_config(config)
    domain = dds_environment.free_domain_id()
    env = child_environment({"ROS_DOMAIN_ID": str(domain),
                             "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    log_dir = Path(log_dir) if log_dir else None
    logs = []

    def start(command, name):
        out = subprocess.DEVNULL
        if log_dir:
            log_dir.mkdir(parents=True, exist_ok=True)
            out = open(log_dir / f"{name}.log", "wb")
            logs.append(out)
        return subprocess.Popen(command, env=env, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, cwd=HERE.parent)

    servers = [
        start([sys.executable, "-m", "sensorispace_ros.graph.nodes.body", "--ros-args",
               "--params-file", str(config)], "body"),
        start([sys.executable, str(HERE / "rclpy_echo.py")], "echo"),
        start([sys.executable, str(HERE / "rclpy_echo.py"), "--lean"], "lean_echo"),
        start([sys.executable, str(HERE / "rclpy_echo.py"), "--simulate", str(config)], "sim_echo"),
    ]
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_probe_client", context=context)
    executor, _ = make_executor(context=context)
    executor.add_node(node)

    def spin(timeout_s):
        executor.spin_once(timeout_sec=timeout_s)
    try:
        # The body node describes the configured body (its /body/description).
        from sensorispace_ros.graph.framework import build_world
        description = build_world(cfg).body().description
        command_columns = contracts.contract("/body/motor_command").columns_for(description)
        sensation_columns = contracts.contract("/body/sensation").columns_for(description)
        lights_columns = contracts.contract("/environment/lights").columns
        command_pub = contracts.create_publisher(node, "/body/motor_command")
        lights_pub = contracts.create_publisher(node, "/environment/lights")

        command_packer = messages.CloudCdrPacker(command_columns)

        def publish_command(motor_states, frame_id):     # as AgentNode.publish_command
            command_pub.publish(command_packer.pack(
                motor_states, frame_id, node.get_clock().handle.get_now().nanoseconds))

        body = BodyOverTopics(publish_command, spin, n_motors=len(command_columns),
                              n_sensors=len(sensation_columns))
        passive = []

        sensation_reader = messages.CloudCdrReader(sensation_columns)

        def on_sensation(raw):                            # as AgentNode.on_sensation
            cloud = sensation_reader.read(raw)
            if cloud.frame_id.startswith("cmd/"):
                body.deliver(cloud.frame_id, cloud.matrix)
            else:
                passive.append(cloud.frame_id)

        contracts.create_subscription(node, "/body/sensation", on_sensation, raw=True)
        ping_pub = node.create_publisher(PointCloud2, rclpy_echo.PING, rclpy_echo.QOS)
        pong = {}
        node.create_subscription(PointCloud2, rclpy_echo.PONG,
                                 lambda msg: pong.__setitem__(msg.header.frame_id, msg),
                                 rclpy_echo.QOS)
        lean_ping_pub = node.create_publisher(PointCloud2, rclpy_echo.LEAN_PING, rclpy_echo.QOS)
        lean_pong = {}
        node.create_subscription(PointCloud2, rclpy_echo.LEAN_PONG,
                                 lambda msg: lean_pong.__setitem__(msg.header.frame_id, msg),
                                 rclpy_echo.QOS)
        sim_ping_pub = node.create_publisher(PointCloud2, rclpy_echo.SIM_PING, rclpy_echo.QOS)
        sim_pong = {}
        echo_work = {}                # rows -> [(simulate, decode)] ms inside the sim echo

        def on_sim_pong(msg):
            sim_pong[msg.header.frame_id] = (messages.cloud_to_matrix(msg, sensation_columns),
                                             msg.header.stamp.nanosec * 1e-6,
                                             msg.header.stamp.sec * 1e-6)

        node.create_subscription(PointCloud2, rclpy_echo.SIM_PONG, on_sim_pong, rclpy_echo.QOS)

        deadline = time.monotonic() + 60.0
        while (command_pub.get_subscription_count() < 1 or ping_pub.get_subscription_count() < 1
               or sim_ping_pub.get_subscription_count() < 1
               or lean_ping_pub.get_subscription_count() < 1
               or node.count_publishers(rclpy_echo.LEAN_PONG) < 1
               or node.count_publishers("/body/sensation") < 1
               or node.count_publishers(rclpy_echo.PONG) < 1
               or node.count_publishers(rclpy_echo.SIM_PONG) < 1):
            if time.monotonic() > deadline:
                raise RuntimeError("servers not discovered within 60 s")
            if any(p.poll() is not None for p in servers):
                raise RuntimeError("a server process exited early")
            spin(0.05)
        world = build_world(cfg)
        lights = messages.matrix_to_cloud(world.initial_lights, lights_columns,
                                          messages.make_header(frame("change", 0)))
        # Re-sent until answered: discovery may not have matched every reader yet
        # (a volatile passive sensation sent before that is lost; seen once).
        resend_at = 0.0
        while not passive:
            if time.monotonic() > deadline:
                raise RuntimeError("the body node never answered the lights")
            if time.monotonic() >= resend_at:
                lights_pub.publish(lights)
                resend_at = time.monotonic() + 1.0
            spin(0.05)

        rng = np.random.default_rng(seed)
        sizes = sorted(per_round)
        motor = {rows: world.m0 + 0.01 * rng.standard_normal((rows, 4)) for rows in sizes}
        pings = {rows: rclpy_echo.float_cloud(rows, 4) for rows in sizes}
        counter = [0]

        def ping(rows, publisher=ping_pub, inbox=pong):
            counter[0] += 1
            frame_id = f"ping/{counter[0]}"
            msg = pings[rows]
            msg.header = messages.make_header(frame_id)
            started = time.perf_counter()
            publisher.publish(msg)
            while frame_id not in inbox:
                spin(0.5)
            elapsed = time.perf_counter() - started
            assert inbox.pop(frame_id).width == rows
            return elapsed

        def lean_ping(rows):
            return ping(rows, lean_ping_pub, lean_pong)

        def sim_ping(rows):
            counter[0] += 1
            frame_id = f"sim/{counter[0]}"
            started = time.perf_counter()
            sim_ping_pub.publish(messages.matrix_to_cloud(
                motor[rows], command_columns, messages.make_header(frame_id)))
            while frame_id not in sim_pong:
                spin(0.5)
            elapsed = time.perf_counter() - started
            reply, simulate_ms, decode_ms = sim_pong.pop(frame_id)
            assert reply.shape == (rows, len(sensation_columns))
            echo_work.setdefault(rows, []).append((simulate_ms, decode_ms))
            return elapsed

        def probe(rows):
            started = time.perf_counter()
            reply = body.sense(motor[rows])
            elapsed = time.perf_counter() - started
            assert reply.shape == (rows, len(sensation_columns))
            return elapsed

        # The body node's simulation of a command (what the bare echo does not do),
        # timed here in the rounds so that it sees the same load as the probes.
        from sensorispace_ros.core.body import SimulatedBody
        sim = SimulatedBody(world.receptors, world.initial_lights, world.m0.copy())

        def simulate(rows):
            started = time.perf_counter()
            sim.sense_with_poses(motor[rows])
            return time.perf_counter() - started

        for rows in sizes:                                # warm-up: first messages allocate
            for _ in range(5):
                probe(rows)
                ping(rows)
                lean_ping(rows)
                sim_ping(rows)
                simulate(rows)
        kinds = [("graph", probe), ("bare", ping), ("lean_bare", lean_ping), ("sim", sim_ping),
                 ("compute", simulate)]
        times = {(kind, rows): [] for kind, _ in kinds for rows in sizes}
        load_before = load()
        # Blocks of consecutive probes per kind, as the agent probes the body. Tried
        # once: alternating kinds every few probes (load 3-4.5) gave 1.43 / 1.62 for
        # 1 row: every server then answers cold, which no real run does.
        for r in range(rounds):
            for rows in sizes:
                for kind, fn in kinds[r % len(kinds):] + kinds[:r % len(kinds)]:
                    times[(kind, rows)].extend(fn(rows) for _ in range(per_round[rows]))
        out = {"load_before": load_before, "load_after": load(), "domain_id": domain,
               "rows": {}}
        for rows in sizes:
            g = np.asarray(times[("graph", rows)]) * 1e3
            b = np.asarray(times[("bare", rows)]) * 1e3
            lean_b = np.asarray(times[("lean_bare", rows)]) * 1e3
            sim_t = np.asarray(times[("sim", rows)]) * 1e3
            sim_work = np.median(echo_work[rows], axis=0)
            compute = float(np.median(times[("compute", rows)])) * 1e3
            out["rows"][str(rows)] = {
                "probes": int(len(g)),
                "graph_median_ms": float(np.median(g)), "graph_mean_ms": float(g.mean()),
                "graph_p90_ms": float(np.percentile(g, 90)),
                "bare_median_ms": float(np.median(b)), "bare_mean_ms": float(b.mean()),
                "bare_p90_ms": float(np.percentile(b, 90)),
                "ratio_median": float(np.median(g) / np.median(b)),
                "lean_bare_median_ms": float(np.median(lean_b)),
                "ratio_median_vs_lean_bare": float(np.median(g) / np.median(lean_b)),
                "ratio_mean": float(g.mean() / b.mean()),
                # SimulatedBody.sense_with_poses of the same rows, median, same rounds.
                "body_compute_ms": compute,
                # Diagnostic: decode + simulate + pack in a bare node (no extra
                # publications, no graph node machinery).
                "sim_echo_median_ms": float(np.median(sim_t)),
                # ... and what the echo itself spent on it (median, in the echo process).
                "sim_echo_simulate_ms": float(sim_work[0]),
                "sim_echo_decode_ms": float(sim_work[1]),
                "ratio_graph_over_sim_echo": float(np.median(g) / np.median(sim_t)),
                # What is left once the body's simulation (which the bare echo
                # does not do) is taken out: the graph's messaging overhead.
                "ratio_median_net_of_compute": float((np.median(g) - compute) / np.median(b)),
                "ratio_median_net_of_simulation": float((np.median(g) - sim_work[0])
                                                        / np.median(b)),
            }
        return out
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
        for proc in servers:
            _stop(proc)
        for log in logs:
            log.close()


if __name__ == "__main__":
    import json
    print(json.dumps(measure(), indent=2))
