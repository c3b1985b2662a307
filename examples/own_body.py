"""A body of one's own, outside the project: ``.venv/bin/python examples/own_body.py``.

A planar arm of two links of 2.5, hinges ``hip`` (at the origin) and ``knee``
commanded in degrees, with three receptors at the tip, on a small frame that
keeps its world orientation: receptor i sits at tip + OFFSETS[i] and
outputs the lights' summed brightness there, sum_l 1 / (1 + |p_i - l|^2).
The sensation pins where the tip is (two numbers for two joints): the agent
finds points of view of dimension 0, except where the arm is straight
(every joint at 0), where it is singular. The node is named ``own_body``.

It honours the topics a body honours (docs/own-body.md) with rclpy,
sensor_msgs and numpy alone, nothing of sensorispace_ros, as a body in
another process or language would.

``--sensor-type uint16`` publishes what a 16-bit ADC would: UINT16 counts,
round(s / FULL_SCALE * 65535), clipped to the ADC's range.

``--own-world N`` (with the agent's ``world.clock: wall``): a body in a world
that changes on its own, as a robot's does. No environment node and no
lights message: the body moves its lights itself, N times, after seeded
exponential gaps of mean ``--change-period`` seconds, whatever the agent
does, and tells nobody. It answers ``/body/hold`` (one message: hold still
until a receptor leaves the band, then answer once) and, once its world has
no change left, answers a hold with ``end/<n>`` and exits.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState, PointCloud2, PointField
from std_msgs.msg import Header

JOINTS = ("hip", "knee")
UNIT, PERIOD = "deg", 360.0
LINKS = (2.5, 2.5)
OFFSETS = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5]])      # one receptor each
RECEPTORS = len(OFFSETS)
FULL_SCALE = 4.0                  # the brightness a 16-bit reading's 65535 stands for

LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
DATA = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                  durability=DurabilityPolicy.VOLATILE)
LIGHTS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.TRANSIENT_LOCAL)


def parse(frame_id: str):
    """(kind, number) of a protocol frame id, or None."""
    kind, _, number = frame_id.partition("/")
    if kind in ("change", "end", "cmd", "next", "hold") and number.isascii() and number.isdigit() \
            and len(number) <= 18:
        return kind, int(number)
    return None


def read_table(msg: PointCloud2, names: tuple[str, ...]) -> np.ndarray | None:
    """The float64 columns ``names`` of a cloud laid out as the contract says, else None."""
    fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    if fields != [(n, 8 * k, PointField.FLOAT64, 1) for k, n in enumerate(names)] \
            or msg.is_bigendian or msg.point_step != 8 * len(names) \
            or len(msg.data) != msg.width * msg.point_step:
        return None
    table = np.frombuffer(bytes(msg.data), "<f8").reshape(msg.width, len(names))
    return table if np.isfinite(table).all() else None


# Sensor types this body can publish: PointField datatype and little-endian dtype.
SENSOR_TYPES = {"float64": (PointField.FLOAT64, np.dtype("<f8")),
                "uint16": (PointField.UINT16, np.dtype("<u2"))}


def table_cloud(rows: np.ndarray, prefix: str, header: Header,
                sensor_type: str = "float64") -> PointCloud2:
    datatype, dtype = SENSOR_TYPES[sensor_type]
    rows = np.ascontiguousarray(rows, dtype=dtype)
    size = dtype.itemsize
    fields = [PointField(name=f"{prefix}{k}", offset=size * k, datatype=datatype, count=1)
              for k in range(rows.shape[1])]
    return PointCloud2(header=header, height=1, width=len(rows), fields=fields,
                       is_bigendian=False, point_step=size * rows.shape[1],
                       row_step=size * rows.shape[1] * len(rows), data=rows.tobytes(),
                       is_dense=True)


def object_layout(rng: np.random.Generator, count: int = 10) -> np.ndarray:
    """An object: ``count`` lights 3.5 to 7 from its centre."""
    angle, radius = rng.uniform(0, 2 * np.pi, count), rng.uniform(3.5, 7.0, count)
    return radius[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])


class OwnBody(Node):

    def __init__(self, sensor_type: str = "float64", own_world: int = 0,
                 change_period_s: float = 0.3, seed: int = 0):
        super().__init__("own_body")
        self.sensor_type = sensor_type
        self.rest = np.zeros(len(JOINTS))    # where the arm rests before its first command
        self.lights = np.zeros((0, 2))
        self.applied = -1                 # the number of the last change applied
        self.over = False                 # end/<k> answered: the run is over
        self.held = None                  # a next/<k> command, before change k
        self.sensation_pub = self.create_publisher(PointCloud2, "/body/sensation", DATA)
        description = self.create_publisher(JointState, "/body/description", LATCHED)
        description.publish(JointState(
            header=Header(frame_id=f"{UNIT}/{RECEPTORS}"), name=list(JOINTS),
            position=[PERIOD] * len(JOINTS)))
        self.create_subscription(PointCloud2, "/body/motor_command", self.on_command, DATA)
        self.changes_left = own_world
        if not own_world:
            self.create_subscription(PointCloud2, "/environment/lights", self.on_lights, LIGHTS)
            return
        # A world of its own: the lights move by themselves (an object on a grid).
        self.rng = np.random.default_rng(seed)
        self.period_s = change_period_s
        self.layout = object_layout(self.rng)
        self.lights = self.layout.copy()           # the object's centre at (0, 0)
        self.holding = None               # (number, motor, low, high, header)
        self.next_change = time.monotonic() + self.rng.exponential(self.period_s)
        self.create_timer(0.01, self.on_clock)
        self.create_subscription(PointCloud2, "/body/hold", self.on_hold, DATA)

    def on_clock(self) -> None:
        """The world changes when its time comes, and tells nobody."""
        if self.changes_left <= 0 or time.monotonic() < self.next_change:
            return
        if self.rng.random() < 0.1:              # now and then a layout no move undoes
            self.layout = object_layout(self.rng)
        centre = self.rng.choice(np.linspace(-6.0, 6.0, 16), size=2)   # a move on a grid
        self.lights = centre + self.layout
        self.changes_left -= 1
        self.next_change = time.monotonic() + self.rng.exponential(self.period_s)
        self.watch()

    def on_hold(self, msg: PointCloud2) -> None:
        frame = parse(msg.header.frame_id)
        names = (*(f"m{k}" for k in range(len(JOINTS))), *(f"low{i}" for i in range(RECEPTORS)),
                 *(f"high{i}" for i in range(RECEPTORS)))
        row = read_table(msg, names)
        if frame is None or frame[0] != "hold" or row is None or len(row) != 1:
            return
        motor, low, high = np.split(row[0], [len(JOINTS), len(JOINTS) + RECEPTORS])
        self.holding = (frame[1], motor[None], low, high, msg.header)
        self.watch()

    def watch(self) -> None:
        """Look at the held state: answer once the sensation leaves the band, or
        with ``end/<n>`` once the world has no change left."""
        if self.holding is None:
            return
        number, motor, low, high, header = self.holding
        if self.changes_left <= 0:
            header.frame_id = f"end/{number}"
            self.holding = None
            self.answer(motor, header)
            self.over = True
            return
        sensed = self.sense(motor)[0]
        if np.any((sensed < low) | (sensed > high)):
            self.holding = None
            self.answer(motor, header)

    def sense(self, motor: np.ndarray) -> np.ndarray:
        """One row of receptor outputs per row of motor states (degrees)."""
        hip, knee = np.deg2rad(motor[:, 0]), np.deg2rad(motor[:, 0] + motor[:, 1])
        tip = np.column_stack([LINKS[0] * np.cos(hip) + LINKS[1] * np.cos(knee),
                               LINKS[0] * np.sin(hip) + LINKS[1] * np.sin(knee)])
        receptors = tip[:, None, :] + OFFSETS[None]                       # (B, R, 2)
        squared = ((receptors[:, :, None, :] - self.lights[None, None]) ** 2).sum(axis=-1)
        brightness = (1.0 / (1.0 + squared)).sum(axis=-1)                 # (B, R)
        if self.sensor_type == "uint16":
            return np.round(np.clip(brightness / FULL_SCALE, 0.0, 1.0) * 65535)
        return brightness

    def answer(self, motor: np.ndarray, header: Header) -> None:
        self.sensation_pub.publish(table_cloud(self.sense(motor), "s", header,
                                                     self.sensor_type))
        self.rest = motor[-1].copy()

    def on_lights(self, msg: PointCloud2) -> None:
        frame = parse(msg.header.frame_id)
        lights = read_table(msg, ("x", "y"))
        if frame is None or frame[0] not in ("change", "end") or lights is None:
            return
        kind, number = frame
        if kind == "change" and len(lights):
            self.lights = lights                         # the end keeps the last lights
        self.applied = max(self.applied, number)
        self.answer(self.rest[None], msg.header)         # the passive sensation
        self.over = self.over or kind == "end"
        if self.held is not None and self.held[0] <= self.applied:
            _, motor, header = self.held
            self.held = None
            self.answer(motor, header)

    def on_command(self, msg: PointCloud2) -> None:
        frame = parse(msg.header.frame_id)
        motor = read_table(msg, tuple(f"m{k}" for k in range(len(JOINTS))))
        if frame is None or frame[0] not in ("cmd", "next", "end") or motor is None \
                or not len(motor):
            return
        self.over = self.over or frame[0] == "end"      # the agent ended the run
        if frame[0] == "next" and frame[1] > self.applied:
            self.held = (frame[1], motor, msg.header)    # answered once change k is applied
            return
        self.answer(motor, msg.header)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="a body of one's own (docs/own-body.md)")
    parser.add_argument("--sensor-type", choices=sorted(SENSOR_TYPES), default="float64",
                        help="what the receptors publish (default float64)")
    parser.add_argument("--own-world", type=int, default=0, metavar="N",
                        help="a world that changes N times on its own (world.clock: wall)")
    parser.add_argument("--change-period", type=float, default=0.3,
                        help="mean seconds between two changes of its own world")
    args, ros_args = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    rclpy.init(args=ros_args)
    node = OwnBody(args.sensor_type, args.own_world, args.change_period)
    try:
        while rclpy.ok() and not node.over:
            rclpy.spin_once(node, timeout_sec=0.2)
        if node.over:                    # the agent must get the end's passive sensation
            node.sensation_pub.wait_for_all_acked(Duration(seconds=2.0))
            node.get_logger().info("run over")
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
