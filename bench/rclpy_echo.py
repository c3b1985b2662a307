"""The bare baseline of the probe benchmark: an rclpy node that answers every
PointCloud2 on ``bench/ping`` with a prebuilt PointCloud2 of ``rows x 6``
float64 on ``bench/pong`` (the size of the body's sensation reply), copying
the request header. No decoding, no computation, one publication per request.

    python bench/rclpy_echo.py      (ROS_DOMAIN_ID / discovery range from the environment)
    python bench/rclpy_echo.py --lean
    python bench/rclpy_echo.py --simulate CONFIG

The bare echo spins the stock ``SingleThreadedExecutor``: what a plain rclpy
node costs (the baseline of the probe target). ``--lean``: the same echo on
``bench/lean_ping`` / ``bench/lean_pong``, spun by the graph's executor
(``graph.framework.make_executor``, as the body and agent nodes), the request
taken as serialized bytes: the floor of a Python ping-pong over rclpy, reported next to
the baseline.

``--simulate``: a diagnostic middle ground, on ``bench/sim_ping`` /
``bench/sim_pong``: take the request's serialized bytes and decode them with
``messages``, simulate the arm and retina (``SimulatedBody.sense_with_poses``),
pack the reply's bytes - the body node's work without its two extra
ground-truth publications and node machinery - spun by the graph's executor.
The reply's header stamp reports the time this took in the echo process (ns:
``sec`` = decoding, ``nanosec`` = simulation).

Runs until SIGTERM/SIGINT.
"""
from __future__ import annotations

import array
import time

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2, PointField

PING, PONG = "bench/ping", "bench/pong"
LEAN_PING, LEAN_PONG = "bench/lean_ping", "bench/lean_pong"
SIM_PING, SIM_PONG = "bench/sim_ping", "bench/sim_pong"
# Same QoS as the contract's /body/motor_command and /body/sensation, so the
# comparison measures the graph's work, not a QoS difference.
QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_ALL,
                 durability=DurabilityPolicy.VOLATILE)


def float_cloud(rows: int, columns: int, header=None) -> PointCloud2:
    """A PointCloud2 of ``rows x columns`` float64 zeros (the wire size of a table)."""
    fields = [PointField(name=f"c{k}", offset=8 * k, datatype=PointField.FLOAT64, count=1)
              for k in range(columns)]
    msg = PointCloud2(height=1, width=rows, fields=fields, is_bigendian=False,
                      point_step=8 * columns, row_step=8 * columns * rows, is_dense=True,
                      data=array.array("B", bytes(8 * columns * rows)))
    if header is not None:
        msg.header = header
    return msg


def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser()
    parser.add_argument("--simulate", default=None, metavar="CONFIG")
    parser.add_argument("--lean", action="store_true")
    args = parser.parse_args(argv)
    rclpy.init()
    node = rclpy.create_node("bench_echo")
    replies: dict[int, PointCloud2] = {}
    if args.simulate is None:
        ping, pong = (LEAN_PING, LEAN_PONG) if args.lean else (PING, PONG)
        pub = node.create_publisher(PointCloud2, pong, QOS)

        def on_ping(msg: PointCloud2) -> None:
            reply = replies.get(msg.width)
            if reply is None:
                reply = replies[msg.width] = float_cloud(msg.width, 6)
            reply.header = msg.header
            pub.publish(reply)

        node.create_subscription(PointCloud2, ping, on_ping, QOS)
    else:
        from sensorispace_ros import config, contracts, messages
        from sensorispace_ros.core.body import SimulatedBody
        from sensorispace_ros.graph.framework import build_world
        world = build_world(config.load_config(args.simulate))
        body = SimulatedBody(world.receptors, world.initial_lights, world.m0.copy())
        command = contracts.contract("/body/motor_command").columns_for(body.description)
        sensation = contracts.contract("/body/sensation").columns_for(body.description)
        pub = node.create_publisher(PointCloud2, SIM_PONG, QOS)
        packer = messages.CloudCdrPacker(sensation)       # as the body node
        reader = messages.CloudCdrReader(command)

        def on_ping(raw: bytes) -> None:                   # serialized, as the body node
            started = time.perf_counter_ns()
            cloud = reader.read(raw)
            motor = cloud.matrix
            simulated = time.perf_counter_ns()
            sensations = body.sense_with_poses(motor)[0]
            # The reply's stamp carries this node's own work (ns): decoding in
            # ``sec``, simulation in ``nanosec`` (< 1 s), for the bench to report.
            simulate_ns = time.perf_counter_ns() - simulated
            decode_ns = simulated - started
            pub.publish(packer.pack(sensations, cloud.frame_id,
                                    decode_ns * 1_000_000_000 + simulate_ns))

        node.create_subscription(PointCloud2, SIM_PING, on_ping, QOS, raw=True)
    if args.lean or args.simulate:
        from sensorispace_ros.graph.framework import make_executor
        executor, _ = make_executor()
    else:
        executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
