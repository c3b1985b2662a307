"""Startup validation of the bag commands, as a user meets it: a subprocess.

Every broken bag gives ONE line on stderr (``sensorispace: error: ...``), no
traceback, and exit code 2, from ``analyze``, ``replay`` and ``bag recover``.
tests/recording covers some of these in-process (cli.main); here the real command
runs, so a traceback printed by an import, a ROS start-up or an atexit hook
would be caught too.

Permission denial (chmod 000) is not among the faults: these tests run as root
in CI, and root reads any file. An MCAP path that is a directory (EISDIR) stands
in for "the operating system refuses to read it".
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.recording.bag_format import (
    SESSION_CONFIG_TOPIC,
    SESSION_CONFIG_TYPE,
    session_config_cdr,
)
from sensorispace_ros.recording.bag_writer import BagWriter

from shared import REPO

SAMPLE = REPO / "bags" / "sample_smoke"
STORE = get_typestore(Stores.ROS2_JAZZY)
COMMANDS = {
    "analyze": lambda bag, tmp: ["analyze", str(bag), "--out", str(tmp / "out")],
    "replay": lambda bag, tmp: ["replay", str(bag), "--fast"],
    "recover": lambda bag, tmp: ["bag", "recover", str(bag)],
}


def _string_cdr(text: str) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types["std_msgs/msg/String"](data=text),
                                     "std_msgs/msg/String"))


def missing(tmp: Path) -> Path:
    return tmp / "absent"


def unreadable_mcap(tmp: Path) -> Path:
    """metadata.yaml intact, but the MCAP cannot be opened (a directory in its place)."""
    bag = tmp / "unreadable"
    shutil.copytree(SAMPLE, bag)
    (bag / "sample_smoke.mcap").unlink()
    (bag / "sample_smoke.mcap").mkdir()
    return bag


def garbage_bag(tmp: Path) -> Path:
    """metadata.yaml and MCAP are both noise (a disk or copy error)."""
    bag = tmp / "garbage"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("::: not yaml [\n")
    (bag / "garbage.mcap").write_bytes(bytes(range(256)) * 40)
    return bag


def truncated_unrecoverable(tmp: Path) -> Path:
    """A recorder killed before its first chunk closed: the MCAP ends inside the header."""
    bag = tmp / "truncated"
    bag.mkdir()
    (bag / "truncated.mcap").write_bytes((SAMPLE / "sample_smoke.mcap").read_bytes()[:40])
    return bag


def foreign_topics_only(tmp: Path) -> Path:
    """A healthy rosbag2 bag of some other system: one std_msgs/String topic."""
    bag = tmp / "foreign"
    with BagWriter(bag, {"/chatter": "std_msgs/msg/String"}) as writer:
        for i in range(5):
            writer.write("/chatter", 1000 + i, _string_cdr(f"hello {i}"))
    return bag


def wrong_type_on_points_of_view(tmp: Path) -> Path:
    """Our topic names, but /agent/points_of_view is not a PointCloud2."""
    bag = tmp / "wrong_type"
    with BagWriter(bag, {"/agent/points_of_view": "std_msgs/msg/String",
                         SESSION_CONFIG_TOPIC: SESSION_CONFIG_TYPE}) as writer:
        writer.write(SESSION_CONFIG_TOPIC, 1000,
                     session_config_cdr((REPO / "config" / "smoke.yaml").read_text()))
        writer.write("/agent/points_of_view", 1001, _string_cdr("not a table"))
    return bag


def killed_foreign_encoding(tmp: Path) -> Path:
    """A killed recorder's MCAP whose channel is JSON, not ros2 CDR (another schema)."""
    from mcap.writer import Writer

    bag = tmp / "killed_json"
    bag.mkdir()
    path = bag / "killed_json.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="test")
        schema = writer.register_schema("Reading", "jsonschema", b"{}")
        channel = writer.register_channel("/agent/points_of_view", "json", schema)
        for i in range(50):
            writer.add_message(channel, log_time=i, data=b'{"v": %d}' % i, publish_time=i)
        writer.finish()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 3 // 4])
    return bag


FAULTS = {
    "missing": (missing, "does not exist"),
    "unreadable": (unreadable_mcap, "is a directory"),
    "garbage": (garbage_bag, ("unreadable", "cannot be recovered")),
    "truncated": (truncated_unrecoverable, None),
    "foreign_topics": (foreign_topics_only, "another schema"),
    "wrong_type": (wrong_type_on_points_of_view, "another schema"),
}
# (fault, command) pairs that are not errors by design: `bag recover` repairs
# files and leaves a complete bag alone, whatever its topics; another schema
# is the business of the commands that read it.
NOT_AN_ERROR = {("foreign_topics", "recover"), ("wrong_type", "recover")}
CASES = [(f, c) for f in FAULTS for c in COMMANDS if (f, c) not in NOT_AN_ERROR]
CASES.append(("killed_foreign_encoding", "recover"))
FAULTS["killed_foreign_encoding"] = (killed_foreign_encoding, "another schema")


def _run(arguments: list[str], tmp: Path, domain_id: int) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(domain_id))
    env.pop("SENSORISPACE_DEBUG", None)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH")) if p)
    return subprocess.run([sys.executable, "-m", "sensorispace_ros.cli", *arguments], cwd=tmp,
                          env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("fault,command", CASES, ids=[f"{c}-{f}" for f, c in CASES])
def test_broken_bag_is_one_line_and_exit_2(tmp_path, domain_id, fault, command):
    make, phrase = FAULTS[fault]
    bag = make(tmp_path)
    done = _run(COMMANDS[command](bag, tmp_path), tmp_path, domain_id)
    err = done.stderr.strip()
    assert done.returncode == 2, (done.returncode, done.stdout, err)
    assert "Traceback" not in done.stderr + done.stdout
    assert len(err.splitlines()) == 1, err
    assert err.startswith("sensorispace: error: "), err
    assert bag.name in err, err           # the user is told which bag
    if phrase is not None:
        phrases = (phrase,) if isinstance(phrase, str) else phrase
        assert any(p in err.lower() for p in phrases), err
    if fault == "truncated" and command != "recover":
        assert "bag recover" in err, err  # the hint to the fix
    if fault == "truncated" and command == "recover":
        assert "cannot be recovered" in err, err
    assert not (tmp_path / "out" / "metrics.json").exists()


def test_recover_leaves_a_complete_foreign_bag_alone(tmp_path, domain_id):
    """Not an error by design (see NOT_AN_ERROR): the bag is whole, and untouched."""
    bag = foreign_topics_only(tmp_path)
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    done = _run(COMMANDS["recover"](bag, tmp_path), tmp_path, domain_id)
    assert done.returncode == 0 and "already complete" in done.stdout, done
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before
