"""``sensorispace compare``: two runs' metrics side by side with their differences."""
from __future__ import annotations

import argparse

from sensorispace_ros.cli.summary import fmt


HELP = "show two runs' metrics side by side"
DESCRIPTION = """
Print the metrics of two runs (run directories or metrics.json files) side by side with
their differences.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("a", metavar="A", help="first run (directory or metrics.json)")
    parser.add_argument("b", metavar="B", help="second run (directory or metrics.json)")
    parser.add_argument("--only-different", action="store_true",
                        help="list only the values that differ")


def run(args: argparse.Namespace) -> int:
    from sensorispace_ros.evaluation.run_files import read_metrics

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
        text = fmt(delta) if not isinstance(delta, int) else f"{delta:+d}"
        if isinstance(delta, float) and not text.startswith("-"):
            text = "+" + text
        if a != 0:
            text += f" ({100.0 * delta / abs(a):+.1f} %)"
        return text
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b) \
            and all(isinstance(v, (int, float)) for v in a + b):
        if a == b:
            return ""
        worst = max(abs(y - x) for x, y in zip(a, b))
        return f"max |diff| {fmt(worst)}"
    return "" if a == b else "differs"


def _metric_rows(a: dict, b: dict, only_different: bool) -> list[tuple[str, str, str, str]]:
    from sensorispace_ros.evaluation.run_files import flatten_metrics

    flat_a = flatten_metrics({k: v for k, v in a.items() if k != "config"})
    flat_b = flatten_metrics({k: v for k, v in b.items() if k != "config"})
    rows = []
    for key in sorted(set(flat_a) | set(flat_b)):
        va, vb = flat_a.get(key), flat_b.get(key)
        present = key in flat_a and key in flat_b
        diff = _difference(va, vb) if present else "only in " + ("A" if key in flat_a else "B")
        if only_different and not diff:
            continue
        rows.append((key, fmt(va), fmt(vb), diff))
    return rows


def compare_table(a: dict, b: dict, name_a: str = "A", name_b: str = "B",
                  only_different: bool = False) -> str:
    """Two runs' metrics side by side: key, A, B, B - A (relative)."""
    config_a, config_b = a.get("config", {}), b.get("config", {})
    rows = _metric_rows(a, b, only_different)
    config_rows = [(key, fmt(config_a.get(key)), fmt(config_b.get(key)), "differs")
                   for key in sorted(set(config_a) | set(config_b))
                   if config_a.get(key) != config_b.get(key)]

    width_key = max([len(r[0]) for r in rows + config_rows] + [6])
    width_a = max([len(r[1]) for r in rows + config_rows] + [len("A")])
    width_b = max([len(r[2]) for r in rows + config_rows] + [len("B")])
    lines = [f"A: {name_a}", f"B: {name_b}",
             f"{'metric':<{width_key}}  {'A':>{width_a}}  {'B':>{width_b}}  B - A"]
    lines += [f"{k:<{width_key}}  {x:>{width_a}}  {y:>{width_b}}  {d}".rstrip()
              for k, x, y, d in rows]
    lines.append("")
    if config_rows:
        lines.append("configuration differences:")
        lines += [f"{k:<{width_key}}  {x:>{width_a}}  {y:>{width_b}}" for k, x, y, _ in config_rows]
    else:
        lines.append("same configuration" if config_a or config_b else "no configuration recorded")
    return "\n".join(lines)
