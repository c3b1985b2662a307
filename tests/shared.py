"""Helpers every test folder shares (``tests/conftest.py`` puts this folder on
``sys.path`` and turns them into fixtures): the repository root, a free TCP
port, and stopping a process by its PID."""
from __future__ import annotations

import signal
import socket
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SMOKE = REPO / "config" / "smoke.yaml"
# How long a stopped process gets to exit after SIGTERM before SIGKILL.
GRACE_S = 10.0


def free_port() -> int:
    """A TCP port nothing listens on now (the OS's choice)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def stop_by_pid(process: subprocess.Popen, grace_s: float = GRACE_S) -> int | None:
    """SIGTERM to ``process`` by its PID, then SIGKILL if it is still alive
    after ``grace_s``; returns its exit code (None if it never started)."""
    if process is None:
        return None
    if process.poll() is None:
        try:
            process.send_signal(signal.SIGTERM)
            process.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        except ProcessLookupError:
            pass
    return process.returncode
