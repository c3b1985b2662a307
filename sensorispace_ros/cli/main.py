"""The ``sensorispace`` command.

Subcommands defined here: ``reproduce`` (run a strategy offline, write
metrics.json + figures) and ``compare`` (two runs side by side). Others are
contributed by their modules: each of ``EXTENSIONS`` provides
``register(subparsers)``, which adds its parsers with
``set_defaults(handler=fn)``, ``fn(args) -> int`` the exit status; it may list
the exception types that are user errors (printed as one line) in
``USER_ERRORS``.

User errors (bad configuration, missing file) print one line
``sensorispace: error: ...`` and exit 2; set ``SENSORISPACE_DEBUG=1`` to get
the traceback instead.
"""
from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
from pathlib import Path
from typing import Sequence

PROG = "sensorispace"
EXTENSIONS = ("sensorispace_ros.graph.launcher", "sensorispace_ros.cli.bag")
EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


def build_parser() -> tuple[argparse.ArgumentParser, tuple[type[BaseException], ...]]:
    parser = argparse.ArgumentParser(
        prog=PROG, description="Discovering space: a naive agent's sensorimotor pipeline.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    reproduce = sub.add_parser(
        "reproduce", help="run a strategy offline; write metrics.json, arrays.npz and figures",
        description="Run the paper's two simulations with one strategy and write "
                    "DIR/metrics.json, DIR/arrays.npz and DIR/figures/*.png.")
    reproduce.add_argument("--strategy", choices=("paper", "naive"), default="paper",
                           help="paper: analytic shortcuts; naive: sensorimotor flow only "
                                "(default: paper)")
    reproduce.add_argument("--seed", type=_seed, default=None,
                           help="seed of every random choice (default: the config's seed)")
    reproduce.add_argument("--out", metavar="DIR", default=None,
                           help="output directory (default: results/<strategy>-seed<S>)")
    reproduce.add_argument("--config", metavar="FILE", default=None,
                           help="parameter file (default: the paper's values, "
                                "as in config/paper.yaml)")
    reproduce.add_argument("--no-figures", action="store_true", help="skip the figures")
    reproduce.add_argument("--quiet", action="store_true", help="no progress display")
    reproduce.set_defaults(handler=run_reproduce)

    compare = sub.add_parser(
        "compare", help="show two runs' metrics side by side",
        description="Print the metrics of two runs (run directories or metrics.json "
                    "files) side by side with their differences.")
    compare.add_argument("a", metavar="A", help="first run (directory or metrics.json)")
    compare.add_argument("b", metavar="B", help="second run (directory or metrics.json)")
    compare.add_argument("--only-different", action="store_true",
                         help="list only the values that differ")
    compare.set_defaults(handler=run_compare)

    user_errors: list[type[BaseException]] = []
    for name in EXTENSIONS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:       # the module exists but one of its imports is missing
                raise
            continue
        module.register(sub)
        user_errors.extend(getattr(module, "USER_ERRORS", ()))
    return parser, tuple(user_errors)


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a non-negative integer, got {text!r}")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    parser, extension_errors = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, OSError, *extension_errors) as exc:
        if os.environ.get("SENSORISPACE_DEBUG"):
            raise
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


# ---------------------------------------------------------------------------
# reproduce


def run_reproduce(args: argparse.Namespace) -> int:
    from sensorispace_ros import config as config_mod
    from sensorispace_ros.offline import pipeline
    from sensorispace_ros.progress import Progress

    overrides = {}
    if args.seed is not None:
        overrides["seed"] = args.seed
    if args.no_figures:
        overrides["output.figures"] = False
    cfg = config_mod.load_config(args.config, overrides)
    out = Path(args.out) if args.out else Path("results") / f"{args.strategy}-seed{cfg['seed']}"
    progress = Progress(enabled=not args.quiet)
    metrics = pipeline.reproduce(cfg, args.strategy, out_dir=out, progress=progress)
    print(summary_table(metrics, out))
    return 0


def _fmt(value, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if value == 0.0:
            return "0"
        if not math.isfinite(value):
            return str(value)
        if abs(value) < 1e-3 or abs(value) >= 1e5:
            return f"{value:.{digits - 1}e}"
        return f"{value:.{digits}g}" if abs(value) < 1 else f"{value:.{digits}f}".rstrip("0").rstrip(".")
    if isinstance(value, list):
        if len(value) <= 3:
            return "[" + ", ".join(_fmt(v, 3) for v in value) + "]"
        return f"[{_fmt(value[0], 3)} .. {_fmt(value[-1], 3)}] ({len(value)})"
    return str(value)


def summary_table(metrics: dict, out: Path | None = None) -> str:
    """A short human summary of one run's metrics.json."""
    def get(path, default=None):
        node = metrics
        for part in path.split("."):
            if not isinstance(node, dict) or part not in node:
                return default
            node = node[part]
        return node

    lines = []
    head = f"{metrics.get('strategy', '?')} strategy, seed {metrics.get('seed', '?')}"
    lines.append(head + (f" -> {out}" if out is not None else ""))
    lines.append(f"  exploration: {_fmt(get('exploration.events'))} events, "
                 f"{_fmt(get('exploration.state_changes'))} state changes, "
                 f"{_fmt(get('exploration.compensated'))} compensated, "
                 f"{_fmt(get('exploration.state_changes_compensated'))} state changes compensated")
    lines.append(f"  points of view: {_fmt(get('pov.count'))}, "
                 f"max pose drift {_fmt(get('pov.max_pose_drift'))}; "
                 f"equality sets: {_fmt(get('equality_sets.count'))} "
                 f"({_fmt(get('equality_sets.pairs'))} changes)")
    naive = get("naive")
    if isinstance(naive, dict) and naive:
        lines.append("  naive: " + ", ".join(f"{k} {_fmt(v)}" for k, v in sorted(naive.items())
                                             if not isinstance(v, (dict, list))))
    columns = ("trustworthiness", "continuity", "spearman", "affine_residual")
    header = f"  {'':12}" + "".join(f"{c:>17}" for c in columns) + f"{'reach straightness':>20}"
    lines.append(header)
    for dim in ("2d", "3d"):
        for stage in ("before", "after"):
            row = f"  {dim.upper() + ' ' + stage:12}"
            row += "".join(f"{_fmt(get(f'quality.{dim}.{stage}.{c}')):>17}" for c in columns)
            row += f"{_fmt(get(f'reaching.{dim}.{stage}.straightness_median')):>20}"
            lines.append(row)
    lines.append(f"  {'Hausdorff':12}" + " " * (17 * len(columns))
                 + f"{_fmt(get('reaching.hausdorff.straightness_median')):>20}")
    timings = get("timings_s") or {}
    order = ("exploration", "points_of_view", "equality_sets", "hausdorff", "cca",
             "regularization", "reaching", "total", "figures")
    shown = [k for k in order if k in timings] + sorted(set(timings) - set(order))
    lines.append("  time (s): " + ", ".join(f"{k} {_fmt(timings[k], 3)}" for k in shown))
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# compare


def run_compare(args: argparse.Namespace) -> int:
    from sensorispace_ros.offline.pipeline import read_metrics

    a, b = read_metrics(args.a), read_metrics(args.b)
    print(compare_table(a, b, str(args.a), str(args.b), only_different=args.only_different))
    return 0


def _difference(a, b) -> str:
    if isinstance(a, bool) or isinstance(b, bool):
        return "" if a == b else "differs"
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if a == b:
            return ""
        delta = b - a
        text = _fmt(delta) if not isinstance(delta, int) else f"{delta:+d}"
        if isinstance(delta, float) and not text.startswith("-"):
            text = "+" + text
        if a != 0 and isinstance(a, (int, float)):
            text += f" ({100.0 * delta / abs(a):+.1f} %)"
        return text
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b) \
            and all(isinstance(v, (int, float)) for v in a + b):
        if a == b:
            return ""
        worst = max(abs(y - x) for x, y in zip(a, b))
        return f"max |diff| {_fmt(worst)}"
    return "" if a == b else "differs"


def compare_table(a: dict, b: dict, name_a: str = "A", name_b: str = "B",
                  only_different: bool = False) -> str:
    """Two runs' metrics side by side: key, A, B, B - A (relative)."""
    from sensorispace_ros.offline.pipeline import flatten_metrics

    config_a, config_b = a.get("config", {}), b.get("config", {})
    flat_a = flatten_metrics({k: v for k, v in a.items() if k != "config"})
    flat_b = flatten_metrics({k: v for k, v in b.items() if k != "config"})
    keys = sorted(set(flat_a) | set(flat_b))
    rows = []
    for key in keys:
        va, vb = flat_a.get(key), flat_b.get(key)
        present = key in flat_a and key in flat_b
        diff = _difference(va, vb) if present else "only in " + ("A" if key in flat_a else "B")
        if only_different and not diff:
            continue
        rows.append((key, _fmt(va), _fmt(vb), diff))
    config_rows = [(key, _fmt(config_a.get(key)), _fmt(config_b.get(key)), "differs")
                   for key in sorted(set(config_a) | set(config_b))
                   if config_a.get(key) != config_b.get(key)]

    width_key = max([len(r[0]) for r in rows + config_rows] + [6])
    width_a = max([len(r[1]) for r in rows + config_rows] + [len("A")])
    width_b = max([len(r[2]) for r in rows + config_rows] + [len("B")])
    lines = [f"A: {name_a}", f"B: {name_b}",
             f"{'metric':<{width_key}}  {'A':>{width_a}}  {'B':>{width_b}}  B - A"]
    lines += [f"{k:<{width_key}}  {x:>{width_a}}  {y:>{width_b}}  {d}".rstrip()
              for k, x, y, d in rows]
    if config_rows:
        lines.append("")
        lines.append("configuration differences:")
        lines += [f"{k:<{width_key}}  {x:>{width_a}}  {y:>{width_b}}" for k, x, y, _ in config_rows]
    else:
        lines.append("")
        lines.append("same configuration" if config_a or config_b else "no configuration recorded")
    return "\n".join(lines)

