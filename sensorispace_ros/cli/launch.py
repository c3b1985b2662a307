"""``sensorispace launch``: the naive agent as a ROS 2 graph, one process per node
(graph.launcher.launch_graph)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sensorispace_ros.graph.live_view import DEFAULT_PORT as DEFAULT_VIEW_PORT


HELP = "run the naive agent as a ROS 2 node graph (one process per node)"
DESCRIPTION = """
Start environment, body, agent, representation (and the recorder, and with --view the
viewer) as separate processes with localhost-only discovery and a private domain id,
follow the run, then write results/<run>/metrics.json and figures.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
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
    parser.add_argument("--no-body", action="store_true",
                        help="leave the simulated body out: a body of your own, started by "
                             "you, takes its place (docs/own-body.md); not evaluated")
    parser.add_argument("--body-node", default="own_body", metavar="NAME",
                        help="with --no-body, the node name of your body (default own_body)")
    parser.add_argument("--view", action="store_true",
                        help="also start the viewer and serve the run to the Foxglove app on "
                             "ws://localhost:<--view-port> (docs/viewing.md)")
    parser.add_argument("--view-port", type=int, default=None, metavar="PORT",
                        help=f"port of the live view (implies --view; default {DEFAULT_VIEW_PORT})")


def run(args: argparse.Namespace) -> int:
    from sensorispace_ros.config import ConfigError
    from sensorispace_ros.graph.launcher import launch_graph

    if args.respawn < 0:
        print(f"sensorispace launch: --respawn must be >= 0, got {args.respawn}", file=sys.stderr)
        return 2
    view_port = 0
    if args.view or args.view_port is not None:
        view_port = DEFAULT_VIEW_PORT if args.view_port is None else args.view_port
        if not 0 < view_port < 65536:
            print(f"sensorispace launch: --view-port must be in 1..65535, got {view_port}",
                  file=sys.stderr)
            return 2
    try:
        result = launch_graph(args.config, args.run, args.domain_id, record=not args.no_record,
                              results_root=args.results, timeout_s=args.timeout,
                              respawn=args.respawn, view_port=view_port,
                              own_body=args.body_node if args.no_body else "")
    except ConfigError as exc:
        print(f"sensorispace launch: invalid configuration: {exc}", file=sys.stderr)
        return 2
    if result.exit_code:
        print(f"sensorispace launch: {result.message}", file=sys.stderr)
    return result.exit_code
