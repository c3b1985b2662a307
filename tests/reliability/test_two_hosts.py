"""Two hosts, simulated: two network namespaces joined by a veth pair.

environment + body run in namespace A (10.231.0.1), agent + representation +
recorder in namespace B (10.231.0.2). The addresses exist inside the
namespaces only; the veth carries no multicast flag, so discovery can only
come from ROS_STATIC_PEERS. The run must finish and equal the single-host
result; namespaces and processes are removed whatever happens.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time

import pytest

from sensorispace_ros.graph import dds_environment

from shared import SMOKE
from .node_processes import NodeProcesses, assert_same_result, command, load_result

pytestmark = [pytest.mark.graph, pytest.mark.slow]

ADDRESSES = {"a": "10.231.0.1", "b": "10.231.0.2"}
TWO_HOST_DOMAIN_ID = 231
PLACEMENT = {"environment": "a", "body": "a", "agent": "b", "representation": "b",
             "recorder": "b"}


def _ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)


def _must(*args: str) -> str:
    done = _ip(*args)
    if done.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {done.stderr.strip()}")
    return done.stdout


@pytest.fixture
def namespaces():
    """Two namespaces joined by a veth pair; deleted (with the veth) at teardown."""
    if shutil.which("ip") is None:
        pytest.skip("iproute2 (`ip`) is not installed")
    tag = f"{os.getpid() % 100000}"
    names = {side: f"ss7{side}-{tag}" for side in ADDRESSES}
    veth = {side: f"ss7{side}{tag}" for side in ADDRESSES}     # <= 15 characters
    created = []
    try:
        for side, ns in names.items():
            done = _ip("netns", "add", ns)
            if done.returncode != 0:
                pytest.skip(f"cannot create network namespaces here: ip netns add: "
                            f"{done.stderr.strip()}")
            created.append(ns)
        _must("link", "add", veth["a"], "type", "veth", "peer", "name", veth["b"])
        for side, ns in names.items():
            _must("link", "set", veth[side], "netns", ns)
            _must("-n", ns, "link", "set", "lo", "up")
            _must("-n", ns, "link", "set", veth[side], "multicast", "off")
            _must("-n", ns, "addr", "add", f"{ADDRESSES[side]}/24", "dev", veth[side])
            _must("-n", ns, "link", "set", veth[side], "up")
        yield {"names": names, "veth": veth}
    finally:
        for ns in created:
            _ip("netns", "del", ns)
        if _ip("link", "show", veth["a"]).returncode == 0:     # never moved into a namespace
            _ip("link", "del", veth["a"])


def _veth_bytes(ns: str, dev: str) -> int:
    stats = _must("-n", ns, "-s", "-j", "link", "show", dev)
    import json
    entry = json.loads(stats)[0]["stats64"]
    return int(entry["tx"]["bytes"]) + int(entry["rx"]["bytes"])


@pytest.mark.timeout(420)
def test_graph_split_over_two_namespaces_equals_the_single_host_run(
        namespaces, tmp_path, single_host_result):
    names, veth = namespaces["names"], namespaces["veth"]
    for side, ns in names.items():
        flags = _must("-n", ns, "link", "show", veth[side])
        assert "MULTICAST" not in flags.split(">")[0], flags
        assert "224.0.0.0" not in _must("-n", ns, "route", "show")
        # The private address exists inside the namespace only.
        assert ADDRESSES[side] not in _must("addr", "show")

    results, bag = tmp_path / "results", tmp_path / "bag"
    # The namespaces have networks of their own, but /dev/shm is shared with the
    # host: a domain id no host-side test uses (free_domain_id: 1..100,
    # tests/recording: 150..229), with ports above the ephemeral range.
    env = dds_environment.graph_environment(TWO_HOST_DOMAIN_ID)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    env["ROS_STATIC_PEERS"] = ";".join(ADDRESSES.values())
    processes = NodeProcesses(tmp_path / "logs")
    started = time.monotonic()
    try:
        for name, side in PLACEMENT.items():
            processes.start(name, command(name, SMOKE, results, bag), env,
                            prefix=("ip", "netns", "exec", names[side]))
        processes.wait_for_representation(timeout_s=360)
        wall_s = time.monotonic() - started
        carried = _veth_bytes(names["a"], veth["a"])
    finally:
        processes.stop()
    assert_same_result(load_result(results), single_host_result)
    assert (bag / "metadata.yaml").is_file(), "the recorder in namespace B closed no bag"
    # Everything the agent side got came over the veth, not shared memory:
    # at least the POV tables (48 bytes a row) crossed it.
    pov_bytes = 48 * len(single_host_result["povs"]) * single_host_result["povs"].shape[1]
    assert carried > pov_bytes, (carried, pov_bytes)
    print(f"two-namespace run: {wall_s:.1f} s wall, {carried / 1e6:.2f} MB over the veth "
          f"(single host {single_host_result['wall_s']:.1f} s)", file=sys.stderr)
