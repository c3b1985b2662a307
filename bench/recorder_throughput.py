"""The recorder's throughput, and what the bag's zstd level costs and saves.

    PYTHONPATH=. python bench/recorder_throughput.py [--messages 20000] [--rows 1]
    PYTHONPATH=. python bench/recorder_throughput.py --bag bags/<run> [--levels 1,3,9,19]

Without ``--bag``: the recorder node (``python -m sensorispace_ros.graph.nodes.recorder``,
write-ahead log on, as in a run) in a child process, in a private domain with
localhost discovery; this process publishes ``--messages`` messages as fast as
it can (half /body/sensation clouds of ``--rows`` x 6 float64, half
/agent/settled), waits until the recorder acknowledged them all, stops it with
SIGTERM and reads its CPU time (``/proc/<pid>/stat``) from before the first
message to the end. ``messages_per_cpu_s`` = messages / the recorder's CPU
seconds is what one core of recorder can take; ``sustained`` is the rate the
recorder logs (bounded by this publisher). The bag is then checked with
``bag verify``.

With ``--bag``: ``BagWriter`` alone (write-ahead log on, a commit every 8
messages) re-writes that bag's messages: messages/s and MB/s of CDR, the new
bag's size against the messages' bytes; and for each ``--levels`` level, zstd's
ratio and speed on the bag's chunks (uncompressed, 1 MiB each): the numbers
that chose the level (docs/bags.md).
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from bench.child import REPO, child_environment, load  # noqa: E402

SENSATION, SETTLED = "/body/sensation", "/agent/settled"
PARAMS = "/**:\n  ros__parameters:\n    seed: 0\n"


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a live process."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def wait_for(condition, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.05)


def recorder_run(messages: int, rows: int, work: Path) -> dict:
    import numpy as np
    import rclpy
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rclpy.node import Node
    from std_msgs.msg import UInt64

    from sensorispace_ros import contracts
    from sensorispace_ros import messages as msgs
    from sensorispace_ros.recording.bag_verify import verify_bag

    domain = 200 + os.getpid() % 30
    env = child_environment({"ROS_DOMAIN_ID": str(domain)})
    (work / "params.yaml").write_text(PARAMS)
    bag = work / "bag"
    recorder = subprocess.Popen(
        [sys.executable, "-m", "sensorispace_ros.graph.nodes.recorder", "--ros-args",
         "--params-file", str(work / "params.yaml"), "-p", f"graph.bag_dir:={bag}",
         "-p", f"recorder.topics:=['{SENSATION}', '{SETTLED}']"],
        env=env, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    try:
        node = Node("bench_publisher", context=context)
        publishers = {t: contracts.create_publisher(node, t) for t in (SENSATION, SETTLED)}
        wait_for(lambda: all(p.get_subscription_count() for p in publishers.values()), 60,
                 "the recorder's subscriptions")
        from sensorispace_ros.core.body_description import BodyDescription
        columns = contracts.contract(SENSATION).columns_for(BodyDescription.revolute(4, 6))
        clouds = [msgs.matrix_to_cloud(np.random.default_rng(i).random((rows, 6)), columns,
                                       msgs.make_header(f"change/{i}", i)) for i in range(100)]
        cpu_before, started = cpu_seconds(recorder.pid), time.monotonic()
        for i in range(messages // 2):
            publishers[SENSATION].publish(clouds[i % 100])
            publishers[SETTLED].publish(UInt64(data=i))
        for publisher in publishers.values():
            publisher.wait_for_all_acked(Duration(seconds=120))
        publish_s = time.monotonic() - started
        time.sleep(1.5)  # the recorder's last batch and chunk
        cpu = cpu_seconds(recorder.pid) - cpu_before
    finally:
        if recorder.poll() is None:
            os.kill(recorder.pid, signal.SIGTERM)
        output, _ = recorder.communicate(timeout=60)
        context.try_shutdown()
    sustained = [line for line in output.splitlines() if "msgs/s sustained" in line]
    report = verify_bag(bag)
    return {"messages": messages, "rows": rows, "recorder_cpu_s": round(cpu, 3),
            "us_per_message": round(1e6 * cpu / messages, 1),
            "messages_per_cpu_s": round(messages / cpu), "publish_s": round(publish_s, 2),
            "sustained_log": sustained[-1].split("closed: ")[-1] if sustained else None,
            "bag_bytes": (bag / "bag.mcap").stat().st_size, "verified": report.messages,
            "load": load()}


def writer_run(source: Path, work: Path) -> dict:
    from sensorispace_ros.recording.bag_reader import bag_info, read_bag
    from sensorispace_ros.recording.bag_writer import BagWriter

    info = bag_info(source)
    rows = list(read_bag(source))
    cdr_bytes = sum(len(r[3]) for r in rows)
    target = work / "rewritten"
    started = time.perf_counter()
    with BagWriter(target, info.topics, write_ahead=True) as writer:
        for n, (topic, _, stamp, cdr) in enumerate(rows, 1):
            writer.write(topic, stamp, cdr)
            if n % 8 == 0:
                writer.commit()
        writer.commit()
    wall = time.perf_counter() - started
    size = (target / "rewritten.mcap").stat().st_size
    return {"messages": len(rows), "messages_per_s": round(len(rows) / wall),
            "cdr_mb_per_s": round(cdr_bytes / wall / 1e6, 1), "cdr_bytes": cdr_bytes,
            "bag_bytes": size, "ratio": round(cdr_bytes / size, 3), "load": load()}


def level_table(source: Path, levels: list[int]) -> list[dict]:
    """zstd ratio and speed per level on the bag's chunks, uncompressed."""
    import zstandard
    from mcap.stream_reader import StreamReader, get_chunk_data_stream
    from mcap.records import Chunk

    from sensorispace_ros.recording.bag_reader import mcap_files

    with mcap_files(source)[0].open("rb") as stream:
        chunks = [get_chunk_data_stream(r)[0].read(r.uncompressed_size)
                  for r in StreamReader(stream, emit_chunks=True).records if isinstance(r, Chunk)]
    raw = sum(len(c) for c in chunks)
    table = []
    for level in levels:
        compressor = zstandard.ZstdCompressor(level=level)
        started = time.perf_counter()
        size = sum(len(compressor.compress(chunk)) for chunk in chunks)
        wall = time.perf_counter() - started
        table.append({"level": level, "ratio": round(raw / size, 3),
                      "mb_per_s": round(raw / wall / 1e6, 1)})
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--messages", type=int, default=20000)
    parser.add_argument("--rows", type=int, default=1, help="rows of each sensation cloud")
    parser.add_argument("--bag", type=Path, help="re-write this bag with BagWriter alone")
    parser.add_argument("--levels", default="1,3,5",
                        help="zstd levels to measure on --bag's chunks (17 and up: minutes)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="recorder-bench-") as tmp:
        if args.bag:
            result = {"writer": writer_run(args.bag, Path(tmp)),
                      "levels": level_table(args.bag, [int(v) for v in args.levels.split(",")])}
        else:
            result = {"recorder": recorder_run(args.messages, args.rows, Path(tmp))}
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
