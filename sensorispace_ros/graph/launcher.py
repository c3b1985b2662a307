"""The whole graph, one process per node (``sensorispace launch``).

No ros2 launch here (no launch/launch_ros wheels exist, ROS_NOTES.md):
children are ``python -m sensorispace_ros.graph.nodes.<name> --ros-args
--params-file CONFIG``, started in their own session so a terminal Ctrl-C
reaches only the launcher, which then stops them by PID (SIGTERM, SIGKILL
after a grace period). Discovery is localhost-only and the domain id is
private unless the user says otherwise (graph.dds_environment). Progress
comes from the environment's progress record (polled: the launcher is not in
the graph). A node that dies is started again as ``RespawnPolicy`` allows;
otherwise the run fails naming it. At the end the run is evaluated
(evaluation.evaluator, ground truth joined there, never in the agent or the
representation): from the bag if one was recorded, otherwise from the
representation node's arrays.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sensorispace_ros.graph.dds_environment import free_domain_id, graph_environment
from sensorispace_ros.evaluation.graph_run import evaluate_run
from sensorispace_ros.evaluation.run_files import metric
from sensorispace_ros.protocol import BODY_CLOCK_FILE, CHECKPOINTS
from sensorispace_ros.recording.completeness import wait_for_complete_recording
from sensorispace_ros.state.environment_record import PROGRESS_FILE, read_progress
from sensorispace_ros.state.clock_truth import split_clock_record
from sensorispace_ros.state.resting_state import peek

GRAPH_NODES = ("environment", "body", "agent", "representation")
RECORDER = "recorder"
# Started with a live view (``view_port``): draws the run for Foxglove and RViz.
VIEWER = "viewer"
# At the end of a run, how long to wait for the recorder to hold the agent's whole
# run (recording.completeness: at once unless the recorder was restarted late).
RECORDING_WAIT_S = 10.0
GRACE_S = 5.0
POLL_S = 0.1
# How often a node that exits with framework.RESTART_EXIT_CODE is started again.
ASKED_RESTARTS = 3
EXIT_INTERRUPTED = 130


def default_config() -> Path:
    source_tree = Path(__file__).resolve().parents[2]
    for candidate in (source_tree / "config" / "paper.yaml",
                      Path(sys.prefix) / "share" / "sensorispace_ros" / "config" / "paper.yaml"):
        if candidate.is_file():
            return candidate
    return Path("config/paper.yaml")


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

    def stop(self, grace_s: float = GRACE_S, last: tuple = (RECORDER, VIEWER)) -> None:
        """SIGTERM by PID, SIGKILL after ``grace_s``; ``last`` (the recorder, the viewer)
        is stopped after the others so it records (shows) everything they sent."""
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
    (``state.environment_record``), polled: no ROS participant in this process,
    so nothing here wakes at every change inside the hand-over the agent
    waits for (as a subscriber to ``/agent/settled`` would)."""

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


class ClockMonitor(Monitor):
    """The progress of a run on the row clock, where no change is settled: the
    row the body's clock stands at (``body.clock``, read without writing,
    ``graph.nodes.body_clock``) and the world state of that row on the
    schedule (``change_row``: ``core.world_clock.change_rows``); past the
    first ``total`` changes, the world replays them for simulation 2."""

    def __init__(self, clock_path: Path, change_row, total_changes: int, stream,
                 interval_s: float = 2.0):
        super().__init__(clock_path, total_changes, stream, interval_s)
        self.change_row = change_row

    def poll(self) -> None:
        saved = peek(self.progress_path)
        now = time.monotonic()
        if saved is None or now - self._last_print < self.interval_s:
            return
        self._last_print = now
        row = int(split_clock_record(saved)[2][0])         # after the last command
        state = int(np.searchsorted(self.change_row, row, side="right"))
        where = f"change {state}/{self.total} ({100.0 * state / max(self.total, 1):.0f} %)" \
            if state <= self.total else f"simulation 2, change {state - self.total}"
        print(f"[launch] row {row:,}: {where} after {now - self.started:.1f} s",
              file=self.stream, flush=True)


def make_monitor(plan: "RunPlan", stream) -> Monitor:
    """The progress shown while ``plan`` runs: the changes settled, or on the
    row clock the row the body's clock stands at."""
    if plan.cfg["world"]["clock"] != "rows":
        return Monitor(plan.checkpoint_dir / PROGRESS_FILE, plan.total_changes, stream)
    from sensorispace_ros.core.world_clock import clock_change_rows
    n_events = plan.total_changes - 1
    return ClockMonitor(plan.checkpoint_dir / BODY_CLOCK_FILE,
                        clock_change_rows(plan.cfg, n_events), n_events, stream)


@dataclass(frozen=True)
class Restart:
    """A dead node to start again: the log its new process writes, and why."""
    name: str
    log_name: str
    happened: str
    done: str
    count: int
    limit: int

    def line(self, pid: int) -> str:
        return (f"[launch] {self.name} {self.happened}; {self.done} "
                f"({self.count}/{self.limit}, pid {pid})")


class RespawnPolicy:
    """Which dead node is started again (same command line; it resumes from the
    run's checkpoints). One that asks for it (exits with ``restart_exit_code``) up
    to ``asked_limit`` times, one killed by a signal up to ``respawn`` times;
    a node that exits with any other code, or past its limit, fails the run."""

    def __init__(self, respawn: int, restart_exit_code: int,
                 asked_limit: int = ASKED_RESTARTS):
        if respawn < 0:
            raise ValueError(f"respawn must be >= 0, got {respawn}")
        self.restart_exit_code = restart_exit_code
        self.limits = {"restart": asked_limit, "respawn": respawn}
        self.counts = {"restart": Counter(), "respawn": Counter()}

    def restart(self, name: str, code: int) -> Restart | None:
        """The restart of ``name``, which exited with ``code``; None: the run fails."""
        if code == self.restart_exit_code:
            kind, happened, done = ("restart", f"asked to be restarted (exit code {code})",
                                    "started again")
        elif code < 0:
            kind, happened, done = "respawn", f"was killed by signal {-code}", "respawned"
        else:
            return None
        counts, limit = self.counts[kind], self.limits[kind]
        if counts[name] >= limit:
            return None
        counts[name] += 1
        return Restart(name, f"{name}.{kind}-{counts[name]}", happened, done, counts[name], limit)


def wait_for_recording(graph: "Graph", bag_dir: Path, stream,
                       timeout_s: float = RECORDING_WAIT_S) -> float | None:
    """Before the nodes are stopped: until the recorder holds the agent's whole
    run (``recording.completeness``), at most ``timeout_s``; says so when it waited."""
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


@dataclass
class RunPlan:
    """Where one launched run puts everything, and which nodes it starts."""
    cfg: dict
    config_path: Path
    run: str
    results_dir: Path
    bag_dir: Path
    domain_id: int
    env: dict
    record: bool
    total_changes: int
    view_port: int = 0              # 0: no viewer
    own_body: str = ""              # the node name of a body of one's own ("": the simulated one)

    @property
    def log_dir(self) -> Path:
        return self.results_dir / "logs"

    @property
    def checkpoint_dir(self) -> Path:
        return self.results_dir / CHECKPOINTS

    @property
    def nodes(self) -> list[str]:
        return ([n for n in GRAPH_NODES if not (self.own_body and n == "body")]
                + ([RECORDER] if self.record else [])
                + ([VIEWER] if self.view_port else []))

    def node_parameters(self, name: str) -> dict:
        """The parameters the launcher gives node ``name`` beyond the parameter file."""
        if name == RECORDER:
            return {"bag_path": str(self.bag_dir)}
        parameters = {"graph.results_dir": str(self.results_dir),
                      "graph.checkpoint_dir": str(self.checkpoint_dir)}
        if name == "environment":
            parameters["graph.wait_for_nodes"] = [n for n in self.nodes if n != "environment"] \
                + ([self.own_body] if self.own_body else [])
        # The representation's exit ends the run; the others are stopped by PID
        # once the recorder holds everything (an exit would count as a death).
        parameters["graph.exit_when_done"] = name == "representation"
        if name == VIEWER:
            parameters["graph.view_port"] = self.view_port
        return parameters


def plan_run(config_path, run, domain_id, record: bool, results_root, bags_root,
             view_port: int = 0, own_body: str = "") -> RunPlan:
    """Load the configuration, name the run, make its log directory and remove what
    an earlier run of the same name persisted (a fresh run must not resume it).
    ``own_body``: the node name of a body of one's own, started by its user,
    in place of the simulated body."""
    from sensorispace_ros import config
    from sensorispace_ros.bodies import run_world

    config_path = Path(config_path) if config_path else default_config()
    cfg = config.load_config(config_path, simulated_body=not own_body)
    run = run or time.strftime(f"graph-seed{cfg['seed']}-%Y%m%d-%H%M%S")
    domain_id = free_domain_id() if domain_id is None else int(domain_id)
    plan = RunPlan(cfg, config_path, run, Path(results_root) / run, Path(bags_root) / run,
                   domain_id, graph_environment(domain_id), record,
                   total_changes=len(run_world(cfg).events) + 1, view_port=int(view_port),
                   own_body=own_body)
    plan.log_dir.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(plan.checkpoint_dir, ignore_errors=True)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = plan.env["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    return plan


def start_nodes(graph: Graph, plan: RunPlan, stream) -> dict[str, list[str]]:
    """Start every node of the plan; returns each one's command line."""
    commands = {}
    for name in plan.nodes:
        commands[name] = node_command(name, plan.config_path, plan.node_parameters(name))
        graph.start(name, commands[name])
        print(f"[launch] started {name} (pid {graph.children[name].pid})", file=stream,
              flush=True)
    return commands


def restart_dead(graph: Graph, commands: dict, dead: dict[str, int], policy: RespawnPolicy,
                 stream) -> tuple[str, int] | None:
    """Start again every dead node the policy allows; returns the first one it does
    not (name, exit code), None if all run again."""
    failed = None
    for name, code in dead.items():
        restart = policy.restart(name, code)
        if restart is None:
            failed = failed or (name, code)
            continue
        graph.start(name, commands[name], log_name=restart.log_name)
        print(restart.line(graph.children[name].pid), file=stream, flush=True)
    return failed


def follow(graph: Graph, plan: RunPlan, commands: dict, policy: RespawnPolicy,
           monitor: Monitor, stop_requested: list, timeout_s: float | None,
           stream) -> tuple[int, str, str | None]:
    """Until the representation has exited 0 (the run is over), a node died that
    may not be restarted, a stop was requested or ``timeout_s`` passed: returns
    (exit code, message, failed node)."""
    started = time.monotonic()
    while True:
        time.sleep(POLL_S)
        monitor.poll()
        if stop_requested:
            return EXIT_INTERRUPTED, "interrupted; children stopped", None
        exited = graph.exited()
        if exited.get("representation") == 0 and len(exited) == 1:
            if plan.record:
                wait_for_recording(graph, plan.bag_dir, stream)
            return 0, "", None
        dead = {n: c for n, c in exited.items() if not (n == "representation" and c == 0)}
        failed = restart_dead(graph, commands, dead, policy, stream)
        if failed is not None:
            name, code = failed
            return 1, (f"node '{name}' died (exit code {code}); "
                       f"see {plan.log_dir / (name + '.log')}"), name
        if timeout_s is not None and time.monotonic() - started > timeout_s:
            return 1, f"timed out after {timeout_s:.0f} s", None


@contextlib.contextmanager
def stop_requests():
    """SIGINT and SIGTERM only noted (in the list yielded) while the graph runs,
    so the launcher stops its children before it exits."""
    requested: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, _: requested.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield requested
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def launch_graph(config_path: str | Path | None = None, run: str | None = None,
                 domain_id: int | None = None, record: bool = True,
                 results_root: str | Path = "results", bags_root: str | Path = "bags",
                 timeout_s: float | None = None, stream=None, on_started=None,
                 respawn: int = 0, view_port: int = 0, own_body: str = "") -> LaunchResult:
    """Start every node as a process, follow the run, stop the children, evaluate.

    ``on_started(graph)`` is called once every child runs (tests use it to
    kill one). Returns a LaunchResult; ``exit_code`` is non-zero and
    ``failed_node`` names the node if one dies. ``respawn``: how many times a
    node killed by a signal is started again (it resumes from
    ``<results>/checkpoints``) before the run fails; a node that exits with an
    error code is never respawned, except one that asks for it
    (``framework.RESTART_EXIT_CODE``), up to ASKED_RESTARTS times a node.
    ``view_port``: also start the viewer, serving the run to the Foxglove app on
    ws://127.0.0.1:<view_port> (0: no viewer). ``own_body``: the node name of
    a body of one's own that takes the simulated body's place (not evaluated:
    the ground truth is the simulated world's).
    """
    from sensorispace_ros.graph.framework import RESTART_EXIT_CODE

    policy = RespawnPolicy(respawn, RESTART_EXIT_CODE)
    stream = sys.stderr if stream is None else stream
    plan = plan_run(config_path, run, domain_id, record, results_root, bags_root, view_port,
                    own_body)
    print(f"[launch] run {plan.run}: ROS_DOMAIN_ID={plan.domain_id}, discovery "
          f"{plan.env['ROS_AUTOMATIC_DISCOVERY_RANGE']}, config {plan.config_path}, "
          f"logs {plan.log_dir}" + (f", bag {plan.bag_dir}" if record else ", not recording"),
          file=stream, flush=True)
    if plan.view_port:
        from sensorispace_ros.graph.live_view import websocket_url
        print(f"[launch] live view on {websocket_url(plan.view_port)}: in the Foxglove app, "
              "Open connection > Foxglove WebSocket (layout: docs/foxglove-layout.json)",
              file=stream, flush=True)
    graph = Graph(plan.env, plan.log_dir)
    monitor = make_monitor(plan, stream)
    result = LaunchResult(1, plan.run, plan.results_dir, plan.domain_id)
    with stop_requests() as stop_requested:
        started = time.monotonic()
        try:
            commands = start_nodes(graph, plan, stream)
            result.pids = {name: p.pid for name, p in graph.children.items()}
            if on_started is not None:
                on_started(graph)
            result.exit_code, result.message, result.failed_node = follow(
                graph, plan, commands, policy, monitor, stop_requested, timeout_s, stream)
        finally:
            graph.stop()
    result.wall_s = time.monotonic() - started
    print(f"[launch] graph {'finished' if result.exit_code == 0 else 'stopped'} after "
          f"{result.wall_s:.1f} s" + (f": {result.message}" if result.message else ""),
          file=stream, flush=True)
    if result.exit_code == 0 and own_body:
        print(f"[launch] results in {plan.results_dir} (a body of one's own: not evaluated)",
              file=stream, flush=True)
    elif result.exit_code == 0:
        result.metrics = evaluate_run(plan.cfg, plan.results_dir, plan.bag_dir if record else None)
        print_summary(result.metrics, plan.results_dir, stream)
    return result


def print_summary(metrics: dict, results_dir: Path, stream) -> None:
    print(f"[launch] results in {results_dir}", file=stream)
    if "outcome" in metrics:
        print(f"  {metrics['outcome']}", file=stream)
    for key in ("exploration.compensated", "pov.count", "naive.coverage", "naive.wrong_poses",
                "quality.2d.after.affine_residual", "quality.2d.after.trustworthiness",
                "reaching.2d.after.straightness_median", "timings_s.total"):
        value = metric(metrics, key)
        if value is not None:
            print(f"  {key:40s} {value}", file=stream)
    stream.flush()
