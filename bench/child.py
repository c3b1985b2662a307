"""Run a command as a child process and measure it: wall time and the child's
own peak resident memory (``os.wait4`` rusage of that PID, so other users'
processes and earlier children do not count).

Also the machine load at the time (``os.getloadavg``): the machine has 2
cores shared with other work, so every number is reported with its load.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def load() -> list[float]:
    """1, 5 and 15 minute load averages (what ``uptime`` prints)."""
    return [round(v, 2) for v in os.getloadavg()]


def child_environment(extra: dict | None = None) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.update(extra or {})
    return env


def run_measured(command: list[str], log_path: Path | None = None, env: dict | None = None,
                 timeout_s: float | None = None) -> dict:
    """Run ``command``; return wall_s, peak_rss_mib (ru_maxrss of this child,
    KiB on Linux), exit code and the load before and after.

    ``os.wait4`` reports the child together with the descendants it waited
    for: cpu_s sums them, peak_rss_mib is the largest single process.
    """
    load_before = load()
    log = open(log_path, "wb") if log_path else subprocess.DEVNULL
    started = time.perf_counter()
    try:
        proc = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT,
                                env=env or child_environment(), cwd=REPO)
        deadline = None if timeout_s is None else started + timeout_s
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if deadline is not None and time.perf_counter() > deadline:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        proc.returncode = os.waitstatus_to_exitcode(status)
    finally:
        if log_path:
            log.close()
    wall = time.perf_counter() - started
    return {"command": command, "exit_code": proc.returncode, "wall_s": wall,
            "peak_rss_mib": usage.ru_maxrss / 1024.0,
            "cpu_s": usage.ru_utime + usage.ru_stime,
            "load_before": load_before, "load_after": load()}


def reproduce_command(config: str | Path, strategy: str, out_dir: str | Path,
                      figures: bool = True) -> list[str]:
    command = [sys.executable, "-m", "sensorispace_ros.cli", "reproduce", "--strategy", strategy,
               "--config", str(config), "--out", str(out_dir), "--quiet"]
    if not figures:
        command.append("--no-figures")
    return command
