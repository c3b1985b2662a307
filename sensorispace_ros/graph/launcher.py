"""``sensorispace launch``: the whole graph, one process per node.

No ros2 launch here (no launch/launch_ros wheels exist, ROS_NOTES.md):
children are ``python -m sensorispace_ros.graph.nodes.<name> --ros-args
--params-file CONFIG``, started in their own session so a terminal Ctrl-C
reaches only the launcher, which then stops them by PID (SIGTERM, SIGKILL
after a grace period). Discovery is localhost-only and the domain id is
private unless the user says otherwise. Progress comes from the
environment's progress record (polled: the launcher is not in the graph).
At the end the run is evaluated (ground truth joined here, as the
evaluator, never in the agent or the representation): from the bag if one
was recorded, otherwise from the representation node's arrays.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from sensorispace_ros.config import ConfigError
from sensorispace_ros.offline.evaluation import evaluate_run
from sensorispace_ros.state.environment_record import PROGRESS_FILE, read_progress
from sensorispace_ros.recording.completeness import wait_for_complete_recording

# Exceptions the `sensorispace` command prints as a one-line user error.
USER_ERRORS = (ConfigError,)
GRAPH_NODES = ("environment", "body", "agent", "representation")
RECORDER = "recorder"
# At the end of a run, how long to wait for the recorder to hold the agent's whole
# run (recording_complete: at once unless the recorder was restarted late).
RECORDING_WAIT_S = 10.0
GRACE_S = 5.0
# Fast DDS binds the unicast metatraffic port 7410 + 250 * domain for the first
# participant of a domain (RTPS port mapping): a bound port = domain in use.
_RTPS_PORT_BASE, _RTPS_DOMAIN_GAIN = 7410, 250


def default_config() -> Path:
    source_tree = Path(__file__).resolve().parents[2]
    for candidate in (source_tree / "config" / "paper.yaml",
                      Path(sys.prefix) / "share" / "sensorispace_ros" / "config" / "paper.yaml"):
        if candidate.is_file():
            return candidate
    return Path("config/paper.yaml")


def free_domain_id(start: int | None = None) -> int:
    """A ROS_DOMAIN_ID in 1..100 no participant on this host uses yet."""
    start = (os.getpid() % 100) + 1 if start is None else start
    for offset in range(100):
        domain = (start - 1 + offset) % 100 + 1
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.bind(("127.0.0.1", _RTPS_PORT_BASE + _RTPS_DOMAIN_GAIN * domain))
            except OSError:
                continue
        return domain
    raise RuntimeError("no free ROS_DOMAIN_ID in 1..100")


# How often a node that exits with nodes.RESTART_EXIT_CODE is started again.
ASKED_RESTARTS = 3

# Participant liveliness of the graph's Fast DDS participants (issue #7). With
# Fast DDS's default 20 s lease a kill -9'd reader stays matched for 20 s and
# never acknowledges, so a RELIABLE + KEEP_ALL writer to it fills its history and
# publish() fails (measured: the body died ~10 s after the recorder was killed).
# A 3 s lease unmatches the dead reader first.
LEASE_DURATION_S = 3
LEASE_ANNOUNCEMENT_S = 1
# Heartbeat period of every reliable writer (Fast DDS's default is 3 s). A reader
# acknowledges what it received when the writer's heartbeat asks, so the agent's
# snapshot, which waits (<= 1 s a publisher) until its reactions were received
# before emptying its journal, timed out on the representation's readers: ~2 s
# for the first snapshot of every run, then none for 100x that (a paper run's
# journal grew to 289 MB). With 100 ms: 0.08 s on the smoke config, six
# snapshots of a paper run in 0.90 s, its journal 50 MB at the end (31 MB recorded).
HEARTBEAT_PERIOD_NS = 100_000_000
# A new participant announces itself this many times, this often, before the
# lease announcements (Fast DDS's default: 5 every 100 ms). Measured between two
# processes of this machine: a node name was seen 0.6 s after its node was
# created in 4 of 5 tries with the default, 0.04-0.12 s in 4 of 5 with 20 every
# 50 ms (one took 1 s with each); the environment starts the run when it sees
# every node.
INITIAL_ANNOUNCEMENTS = 20
INITIAL_ANNOUNCEMENT_PERIOD_NS = 50_000_000
FASTDDS_PROFILE_XML = f"""<?xml version="1.0" encoding="UTF-8" ?>
<!-- written by sensorispace_ros.graph.launcher: short participant lease (issue #7),
     quick initial announcements (start-up), frequent writer heartbeats
     (acknowledgements the agent's snapshots wait for) -->
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <participant profile_name="sensorispace_graph" is_default_profile="true">
      <rtps>
        <builtin>
          <discovery_config>
            <leaseDuration><sec>{LEASE_DURATION_S}</sec></leaseDuration>
            <leaseAnnouncement><sec>{LEASE_ANNOUNCEMENT_S}</sec></leaseAnnouncement>
            <initialAnnouncements>
              <count>{INITIAL_ANNOUNCEMENTS}</count>
              <period><sec>0</sec><nanosec>{INITIAL_ANNOUNCEMENT_PERIOD_NS}</nanosec></period>
            </initialAnnouncements>
          </discovery_config>
        </builtin>
      </rtps>
    </participant>
    <data_writer profile_name="sensorispace_writer" is_default_profile="true">
      <times>
        <heartbeatPeriod><sec>0</sec><nanosec>{HEARTBEAT_PERIOD_NS}</nanosec></heartbeatPeriod>
      </times>
    </data_writer>
  </profiles>
</dds>
"""


def fastdds_profile_file(directory: str | Path | None = None) -> Path:
    """The graph's Fast DDS XML profile (a default participant profile with a short
    lease, a default writer profile with frequent heartbeats), written atomically
    once per content; Jazzy's Fast DDS 2.14 loads the
    file named by FASTRTPS_DEFAULT_PROFILES_FILE (not FASTDDS_...) and rmw_fastrtps
    creates every participant from the default participant profile."""
    import hashlib
    import tempfile
    directory = Path(directory or tempfile.gettempdir())
    digest = hashlib.sha256(FASTDDS_PROFILE_XML.encode()).hexdigest()[:12]
    path = directory / f"sensorispace_fastdds_{digest}.xml"
    if not path.is_file():
        directory.mkdir(parents=True, exist_ok=True)
        staging = path.with_name(f".{path.name}.{os.getpid()}")
        staging.write_text(FASTDDS_PROFILE_XML)
        os.replace(staging, path)
    return path


def graph_environment(domain_id: int, base: dict | None = None,
                      profile_dir: str | Path | None = None) -> dict:
    """The children's environment: private domain, localhost discovery unless the user
    chose a range, and the short-lease Fast DDS profile unless the user set one."""
    env = dict(os.environ if base is None else base)
    # Localhost-only discovery unless the user chose a range explicitly.
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if not env.get("FASTRTPS_DEFAULT_PROFILES_FILE"):
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(fastdds_profile_file(profile_dir))
    env["ROS_DOMAIN_ID"] = str(domain_id)
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def node_command(name: str, config_path: Path, parameters: dict) -> list[str]:
    command = [sys.executable, "-m", f"sensorispace_ros.graph.nodes.{name}", "--ros-args",
               "--params-file", str(config_path)]
    for key, value in parameters.items():
        if isinstance(value, (list, tuple)):
            value = "[" + ",".join(str(v) for v in value) + "]"
        elif isinstance(value, bool):
            value = str(value).lower()
        command += ["-p", f"{key}:={value}"]
    return command


@dataclass
class LaunchResult:
    exit_code: int
    run: str
    results_dir: Path
    domain_id: int
    failed_node: str | None = None
    wall_s: float = 0.0
    metrics: dict | None = None
    message: str = ""
    pids: dict = field(default_factory=dict)


class Graph:
    """The child processes of one run, stopped by PID."""

    def __init__(self, env: dict, log_dir: Path):
        self.env = env
        self.log_dir = log_dir
        self.children: dict[str, subprocess.Popen] = {}
        self._logs = []

    def start(self, name: str, command: list[str], log_name: str | None = None) -> None:
        log = open(self.log_dir / f"{log_name or name}.log", "wb")
        self._logs.append(log)
        self.children[name] = subprocess.Popen(command, env=self.env, stdout=log,
                                               stderr=subprocess.STDOUT, start_new_session=True)

    def exited(self) -> dict[str, int]:
        return {name: p.returncode for name, p in self.children.items() if p.poll() is not None}

    def stop(self, grace_s: float = GRACE_S, last: tuple = (RECORDER,)) -> None:
        """SIGTERM by PID, SIGKILL after ``grace_s``; ``last`` (the recorder) is stopped
        after the others so it records everything they sent."""
        first = [n for n in self.children if n not in last]
        for group in (first, [n for n in self.children if n in last]):
            procs = [self.children[n] for n in group]
            for proc in procs:
                if proc.poll() is None:
                    os.kill(proc.pid, signal.SIGTERM)
            deadline = time.monotonic() + grace_s
            for proc in procs:
                try:
                    proc.wait(timeout=max(0.0, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    os.kill(proc.pid, signal.SIGKILL)
                    proc.wait()
        for log in self._logs:
            log.close()


class Monitor:
    """Shows the run's progress from the environment's progress record
    (``environment_progress``), polled: no ROS participant in this process,
    so nothing here wakes at every change inside the hand-over the agent
    waits for (a subscriber to ``/agent/settled`` did, 4,230 times a paper
    run)."""

    def __init__(self, progress_path: Path, total_changes: int, stream,
                 interval_s: float = 2.0):
        self.progress_path = Path(progress_path)
        self.total = total_changes
        self.settled = -1
        self.stream = stream
        self.interval_s = float(interval_s)
        self.started = time.monotonic()
        self._last_print = 0.0

    def poll(self) -> None:
        progress = read_progress(self.progress_path)
        if progress is None:
            return
        self.settled = max(self.settled, progress[1])
        now = time.monotonic()
        if now - self._last_print >= self.interval_s and self.settled >= 0:
            self._last_print = now
            done = min(self.settled, self.total)
            print(f"[launch] change {done}/{self.total} ({100.0 * done / max(self.total, 1):.0f} %)"
                  f" after {now - self.started:.1f} s", file=self.stream, flush=True)


def wait_for_recording(graph: "Graph", bag_dir: Path, stream,
                       timeout_s: float = RECORDING_WAIT_S) -> float | None:
    """Before the nodes are stopped: until the recorder holds the agent's whole
    run (``recording_complete``), at most ``timeout_s``; says so when it waited."""
    recorder = graph.children.get(RECORDER)
    if recorder is None:
        return None
    waited = wait_for_complete_recording(bag_dir, timeout_s,
                                         alive=lambda: recorder.poll() is None)
    if waited is None:
        print(f"[launch] the recorder does not hold the agent's whole run after "
              f"{timeout_s:.0f} s (restarted late?); stopping anyway: "
              f"`sensorispace analyze` of {bag_dir} may lack POVs", file=stream, flush=True)
    elif waited > 0.5:
        print(f"[launch] waited {waited:.1f} s for the recorder to hold the agent's whole run",
              file=stream, flush=True)
    return waited


def launch_graph(config_path: str | Path | None = None, run: str | None = None,
                 domain_id: int | None = None, record: bool = True,
                 results_root: str | Path = "results", bags_root: str | Path = "bags",
                 timeout_s: float | None = None, stream=None, on_started=None,
                 respawn: int = 0) -> LaunchResult:
    """Start every node as a process, follow the run, stop the children, evaluate.

    ``on_started(graph)`` is called once every child runs (tests use it to
    kill one). Returns a LaunchResult; ``exit_code`` is non-zero and
    ``failed_node`` names the node if one dies. ``respawn``: how many times a
    node killed by a signal is started again (same command line; it resumes
    from ``<results>/checkpoints``, issue #7) before the run fails; a node
    that exits with an error code is never respawned, except one that asks
    for it (``nodes.RESTART_EXIT_CODE``), up to ASKED_RESTARTS times a node.
    """
    if respawn < 0:
        raise ValueError(f"respawn must be >= 0, got {respawn}")
    from sensorispace_ros import config
    from sensorispace_ros.graph.framework import RESTART_EXIT_CODE, build_world
    stream = sys.stderr if stream is None else stream
    config_path = Path(config_path) if config_path else default_config()
    cfg = config.load_config(config_path)
    run = run or time.strftime(f"graph-seed{cfg['seed']}-%Y%m%d-%H%M%S")
    results_dir = Path(results_root) / run
    log_dir = results_dir / "logs"
    log_dir.mkdir(parents=True, exist_ok=True)
    # a fresh run: what an earlier run of the same name persisted must not be resumed
    checkpoint_dir = results_dir / "checkpoints"
    shutil.rmtree(checkpoint_dir, ignore_errors=True)
    domain_id = free_domain_id() if domain_id is None else int(domain_id)
    env = graph_environment(domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    total = len(build_world(cfg).events) + 1
    has_recorder = record and importlib.util.find_spec(
        f"sensorispace_ros.graph.nodes.{RECORDER}") is not None
    bag_dir = Path(bags_root) / run
    print(f"[launch] run {run}: ROS_DOMAIN_ID={domain_id}, discovery "
          f"{env['ROS_AUTOMATIC_DISCOVERY_RANGE']}, config {config_path}, logs {log_dir}"
          + (f", bag {bag_dir}" if has_recorder else ", not recording"), file=stream, flush=True)

    nodes = list(GRAPH_NODES) + ([RECORDER] if has_recorder else [])
    graph = Graph(env, log_dir)
    monitor = Monitor(checkpoint_dir / PROGRESS_FILE, total, stream)
    result = LaunchResult(1, run, results_dir, domain_id)
    stop_requested = []
    previous = {sig: signal.signal(sig, lambda signum, _: stop_requested.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    started = time.monotonic()
    try:
        commands, respawned, asked = {}, {}, {}
        for name in nodes:
            parameters = {"graph.results_dir": str(results_dir),
                          "graph.checkpoint_dir": str(checkpoint_dir)}
            if name == "environment":
                parameters["graph.wait_for_nodes"] = [n for n in nodes if n != "environment"]
            if name == "representation":
                parameters["graph.exit_when_done"] = True
            if name == RECORDER:
                parameters = {"bag_path": str(bag_dir)}
            commands[name] = node_command(name, config_path, parameters)
            graph.start(name, commands[name])
            print(f"[launch] started {name} (pid {graph.children[name].pid})", file=stream,
                  flush=True)
        result.pids = {name: p.pid for name, p in graph.children.items()}
        if on_started is not None:
            on_started(graph)
        while True:
            time.sleep(0.1)
            monitor.poll()
            if stop_requested:
                result.exit_code, result.message = 130, "interrupted; children stopped"
                break
            exited = graph.exited()
            if exited.get("representation") == 0 and len(exited) == 1:
                result.exit_code = 0
                if has_recorder:
                    wait_for_recording(graph, bag_dir, stream)
                break
            dead = {n: c for n, c in exited.items() if not (n == "representation" and c == 0)}
            for name, code in list(dead.items()):
                # started again: a node that asks for it, or one killed by a signal
                if code == RESTART_EXIT_CODE:
                    kind, counts, limit = "restart", asked, ASKED_RESTARTS
                    happened, done = f"asked to be restarted (exit code {code})", "started again"
                elif code < 0:
                    kind, counts, limit = "respawn", respawned, respawn
                    happened, done = f"was killed by signal {-code}", "respawned"
                else:
                    continue
                if counts.get(name, 0) >= limit:
                    continue
                counts[name] = counts.get(name, 0) + 1
                graph.start(name, commands[name], log_name=f"{name}.{kind}-{counts[name]}")
                del dead[name]
                print(f"[launch] {name} {happened}; {done} ({counts[name]}/{limit}, pid "
                      f"{graph.children[name].pid})", file=stream, flush=True)
            if dead:
                name, code = next(iter(dead.items()))
                result.failed_node = name
                result.exit_code = 1
                result.message = (f"node '{name}' died (exit code {code}); "
                                  f"see {log_dir / (name + '.log')}")
                break
            if timeout_s is not None and time.monotonic() - started > timeout_s:
                result.message = f"timed out after {timeout_s:.0f} s"
                break
    finally:
        graph.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    result.wall_s = time.monotonic() - started
    print(f"[launch] graph {'finished' if result.exit_code == 0 else 'stopped'} after "
          f"{result.wall_s:.1f} s" + (f": {result.message}" if result.message else ""),
          file=stream, flush=True)
    if result.exit_code == 0:
        result.metrics = evaluate_run(cfg, results_dir, bag_dir if has_recorder else None)
        print_summary(result.metrics, results_dir, stream)
    return result


def print_summary(metrics: dict, results_dir: Path, stream) -> None:
    def get(path):
        node = metrics
        for part in path.split("."):
            if not isinstance(node, dict) or part not in node:
                return None
            node = node[part]
        return node
    print(f"[launch] results in {results_dir}", file=stream)
    for key in ("exploration.compensated", "pov.count", "naive.coverage", "naive.wrong_poses",
                "quality.2d.after.affine_residual", "quality.2d.after.trustworthiness",
                "reaching.2d.after.straightness_median", "timings_s.total"):
        value = get(key)
        if value is not None:
            print(f"  {key:40s} {value}", file=stream)
    stream.flush()


def register(subparsers) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "launch", help="run the naive agent as a ROS 2 node graph (one process per node)",
        description="Start environment, body, agent, representation (and the recorder) as "
                    "separate processes with localhost-only discovery and a private domain id, "
                    "follow the run, then write results/<run>/metrics.json and figures.")
    parser.add_argument("--config", type=Path, default=None,
                        help="ROS parameter file (default: config/paper.yaml)")
    parser.add_argument("--run", default=None, help="run name (default: graph-seed<S>-<time>)")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID (default: a free one in 1..100, printed)")
    parser.add_argument("--no-record", action="store_true", help="do not start the recorder")
    parser.add_argument("--results", type=Path, default=Path("results"),
                        help="results root (default: results)")
    parser.add_argument("--timeout", type=float, default=None, help="give up after this many s")
    parser.add_argument("--respawn", type=int, nargs="?", const=3, default=0, metavar="N",
                        help="start a node killed by a signal again, up to N times per node "
                             "(N = 3 if omitted; default 0: the run fails at once); it "
                             "resumes from results/<run>/checkpoints")
    parser.set_defaults(func=run, handler=run)
    return parser


def run(args) -> int:
    from sensorispace_ros.config import ConfigError
    if args.respawn < 0:
        print(f"sensorispace launch: --respawn must be >= 0, got {args.respawn}", file=sys.stderr)
        return 2
    try:
        result = launch_graph(args.config, args.run, args.domain_id, record=not args.no_record,
                              results_root=args.results, timeout_s=args.timeout,
                              respawn=args.respawn)
    except ConfigError as exc:
        print(f"sensorispace launch: invalid configuration: {exc}", file=sys.stderr)
        return 2
    if result.exit_code:
        print(f"sensorispace launch: {result.message}", file=sys.stderr)
    return result.exit_code


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="sensorispace")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    raise SystemExit(main())


def parameter_overrides(config_path: str | Path, graph: dict | None = None) -> list:
    """The parameter file (and ``graph.*`` values) as rclpy Parameters, for in-process nodes."""
    from rclpy.parameter import Parameter

    from sensorispace_ros import config
    flat = config.flatten(config.read_parameter_file(config_path))
    flat.update(graph or {})
    return [Parameter(name, value=value) for name, value in flat.items()]


def run_graph_in_process(config_path: str | Path, domain_id: int, results_dir: str | Path,
                         extra_nodes=(), timeout_s: float = 600.0, on_spin=None,
                         parameters: dict | None = None, node_factories: dict | None = None
                         ) -> dict:
    """All four nodes in this process on one SingleThreadedExecutor and a private Context.

    ``extra_nodes``: callables ``context -> Node`` added to the same executor
    (tests add observers or hostile publishers). ``on_spin(nodes, replace)`` is
    called after every spin; ``replace(name)`` destroys that node, puts a fresh
    one from its factory in its place and returns the old one (tests "kill" and
    restart a node). ``parameters``: more ``graph.*`` parameters for every node;
    ``node_factories``: ``name -> callable(context=, parameter_overrides=)``
    in place of a node class. Returns ``{"nodes": {...}, "wall_s": ...}`` once
    the representation is written; raises TimeoutError otherwise.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from sensorispace_ros.graph.nodes.agent import AgentNode
    from sensorispace_ros.graph.nodes.body import BodyNode
    from sensorispace_ros.graph.nodes.environment import EnvironmentNode
    from sensorispace_ros.graph.nodes.representation import RepresentationNode

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = Context()
    rclpy.init(context=context, domain_id=int(domain_id),
               signal_handler_options=SignalHandlerOptions.NO)
    overrides = parameter_overrides(config_path, {"graph.results_dir": str(results_dir),
                                                  "graph.resend_period_s": 0.5,
                                                  **(parameters or {})})
    factories = {"representation": RepresentationNode, "body": BodyNode, "agent": AgentNode,
                 "environment": EnvironmentNode, **(node_factories or {})}
    nodes: dict = {}
    executor = SingleThreadedExecutor(context=context)

    def add(name: str, node) -> None:
        node.spin_once = lambda timeout_s: executor.spin_once(timeout_sec=timeout_s)
        executor.add_node(node)
        nodes[name] = node

    def replace(name: str):
        old = nodes[name]
        executor.remove_node(old)
        old.destroy_node()
        add(name, factories[name](context=context, parameter_overrides=overrides))
        return old

    try:
        for name, make in factories.items():
            add(name, make(context=context, parameter_overrides=overrides))
        for k, make in enumerate(extra_nodes):
            add(f"extra{k}", make(context))
        started = time.monotonic()
        while nodes["representation"].result is None:
            if nodes["agent"].finished or nodes["representation"].finished:
                raise RuntimeError("a node failed; see its log")
            if time.monotonic() - started > timeout_s:
                raise TimeoutError(f"graph did not finish within {timeout_s} s")
            executor.spin_once(timeout_sec=0.1)
            for node in nodes.values():
                step = getattr(node, "step", None)
                if step is not None:
                    step()
            if on_spin is not None:
                on_spin(nodes, replace)
        return {"nodes": nodes, "wall_s": time.monotonic() - started}
    finally:
        if "agent" in nodes:
            nodes["agent"].abort()      # unblocks the agent's worker if it still waits
        executor.shutdown()
        for node in nodes.values():
            node.destroy_node()
        context.try_shutdown()
