"""Start the graph's nodes as separate processes (optionally inside a network
namespace), follow them, and stop every one by PID. Shared by the two-host,
fuzz and restart tests and by fuzz_graph.py."""
from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np

from sensorispace_ros.graph import launcher
from sensorispace_ros.protocol import RESULT_FILE
from shared import stop_by_pid

NODES = ("environment", "body", "agent", "representation", "recorder")


def node_parameters(name: str, results_dir: Path, bag_dir: Path, nodes=NODES) -> dict:
    """The launcher's per-node parameters (launcher.launch_graph does the same)."""
    if name == "recorder":
        return {"bag_path": str(bag_dir)}
    parameters = {"graph.results_dir": str(results_dir),
                  "graph.checkpoint_dir": str(Path(results_dir) / "checkpoints")}
    if name == "environment":
        parameters["graph.wait_for_nodes"] = [n for n in nodes if n != "environment"]
    # The representation's exit ends the run; the others are stopped by PID
    # once the recorder holds everything (an exit would count as a death).
    parameters["graph.exit_when_done"] = name == "representation"
    return parameters


class NodeProcesses:
    """Child processes by node name; ``stop()`` sends SIGTERM then SIGKILL by PID."""

    def __init__(self, log_dir: Path):
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.children: dict[str, subprocess.Popen] = {}
        self._logs = []

    def start(self, name: str, command: list[str], env: dict, prefix=(), log_name=None) -> int:
        log = open(self.log_dir / f"{log_name or name}.log", "ab")
        self._logs.append(log)
        self.children[name] = subprocess.Popen([*prefix, *command], env=env, stdout=log,
                                               stderr=subprocess.STDOUT, start_new_session=True)
        return self.children[name].pid

    def exited(self) -> dict[str, int]:
        return {n: p.returncode for n, p in self.children.items() if p.poll() is not None}

    def rss_mb(self) -> dict[str, float]:
        """Resident set size of each live child (VmRSS from /proc)."""
        sizes = {}
        for name, proc in self.children.items():
            try:
                for line in Path(f"/proc/{proc.pid}/status").read_text().splitlines():
                    if line.startswith("VmRSS:"):
                        sizes[name] = int(line.split()[1]) / 1024.0
            except (FileNotFoundError, ProcessLookupError):
                pass
        return sizes

    def kill9(self, name: str) -> None:
        proc = self.children[name]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()

    def wait_for_representation(self, timeout_s: float) -> None:
        """Until the representation exits 0; AssertionError if any node dies first."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            exited = self.exited()
            if exited.get("representation") == 0:
                return
            dead = {n: c for n, c in exited.items() if n != "representation" or c != 0}
            if dead:
                raise AssertionError(f"node(s) died: {dead}; logs in {self.log_dir}")
            time.sleep(0.2)
        raise AssertionError(f"the graph did not finish within {timeout_s} s; logs in {self.log_dir}")

    def wait_for_recording(self, bag_dir: Path, timeout_s: float = 10.0) -> float | None:
        """As the launcher does before it stops a finished run: until the recorder
        holds the agent's whole run (``<bag>.complete``); seconds waited, or None."""
        from sensorispace_ros.recording.completeness import wait_for_complete_recording
        recorder = self.children.get("recorder")
        if recorder is None:
            return None
        return wait_for_complete_recording(bag_dir, timeout_s,
                                           alive=lambda: recorder.poll() is None)

    def stop(self) -> None:
        order = [n for n in self.children if n != "recorder"] + \
                [n for n in self.children if n == "recorder"]
        for name in order:
            stop_by_pid(self.children[name])
        for log in self._logs:
            log.close()
        self._logs = []


def command(name: str, config: Path, results_dir: Path, bag_dir: Path) -> list[str]:
    return launcher.node_command(name, Path(config), node_parameters(name, results_dir, bag_dir))


def load_result(results_dir: Path) -> dict:
    with np.load(Path(results_dir) / RESULT_FILE) as stored:
        return {key: stored[key] for key in stored.files}


def assert_same_result(got: dict, reference: dict) -> None:
    """POVs, equality rows and every embedding equal; the agent's counters equal."""
    assert len(got["povs"]) == len(reference["povs"]) > 3
    for key in ("pov_ids", "povs", "pairs", "set_ids"):
        np.testing.assert_array_equal(got[key], reference[key], err_msg=key)
    for key in sorted(k for k in reference if k.startswith("embedding_")):
        np.testing.assert_allclose(got[key], reference[key], rtol=0, atol=1e-9, err_msg=key)
    for key in ("agent_points_of_view", "agent_compensated", "agent_compensation_rows",
                "agent_changes"):
        assert int(got[key]) == int(reference[key]), key
