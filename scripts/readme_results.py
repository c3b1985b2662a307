"""The README's result table, rendered from the metrics.json of one run of each strategy.

  .venv/bin/python scripts/readme_results.py           # run both strategies, then render
  .venv/bin/python scripts/readme_results.py --render  # render from docs/readme-metrics/ only
  .venv/bin/python scripts/readme_results.py --check   # exit 1 if the README's table differs

The runs (seed 0, about 7 minutes of one core) are ``sensorispace reproduce
--strategy <paper|naive> --config config/paper.yaml --no-figures``; only
their metrics.json is kept, in
docs/readme-metrics/<strategy>-seed0/. tests/test_readme_results.py checks that the
README's table is the one rendered from those files and that they were made
with the current config/paper.yaml.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
RESULTS = REPO / "docs" / "readme-metrics"
CONFIG = REPO / "config" / "paper.yaml"
STRATEGIES = ("paper", "naive")
HEADER = "| result | paper | `paper` strategy | `naive` strategy |"


def metrics_path(strategy: str, results: Path = RESULTS) -> Path:
    return results / f"{strategy}-seed0" / "metrics.json"


def value(metrics: dict, dotted: str):
    node = metrics
    for part in dotted.split("."):
        node = node[part]
    return node


def sci(number: float) -> str:
    """2 significant digits, exponent without its leading zero: 1.4e-6."""
    mantissa, exponent = f"{number:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def render(paper: dict, naive: dict) -> str:
    """The table, one row per result: the paper's own words, then each strategy's numbers."""
    p, n = (lambda key: value(paper, key)), (lambda key: value(naive, key))
    m0 = ", ".join(f"{v:g}" for v in p("config")["arm.initial_motor_state"])
    iterations = p("config")["representation.regularization.iterations"]
    rows = [
        (f"points of view from m0 = [{m0}] (compensated grid positions)", '648 of "64²"',
         f"**{p('pov.count')}** ({p('exploration.compensated')} compensated)",
         f"**{n('pov.count')}**: coverage **{n('naive.coverage'):.3f}** of the paper "
         "strategy's (distinct positions over its count), at its very positions "
         f"(`naive.coverage_of_paper_positions` {n('naive.coverage_of_paper_positions'):.3f})"),
        ("state changes (redistributions) compensated", "0",
         f"**{p('exploration.state_changes_compensated')}** of {p('exploration.state_changes')}",
         f"**{n('exploration.state_changes_compensated')}** of {n('exploration.state_changes')}"),
        ("wrong poses accepted", "–", "–", f"**{n('naive.wrong_poses')}**"),
        ("POV pose drift (max over all samples)", "–", f"**{sci(p('pov.max_pose_drift'))}**",
         f"**{sci(n('pov.max_pose_drift'))}**"),
        ("2-D before regularisation: affine residual / trustworthiness", '"cut"',
         *(f"**{m('quality.2d.before.affine_residual'):.3f}** / "
           f"{m('quality.2d.before.trustworthiness'):.3f}" for m in (p, n))),
        (f"2-D after {iterations} iterations: affine residual / trustworthiness",
         '"almost a perfect mapping"',
         *(f"**{sci(m('quality.2d.after.affine_residual'))}** / "
           f"**{m('quality.2d.after.trustworthiness'):.4f}**" for m in (p, n))),
        ("reaching straightness (median of 100 pairs), 2-D before → after",
         '"curved" → "straight"',
         *(f"**{m('reaching.2d.before.straightness_median'):.3f} → "
           f"{m('reaching.2d.after.straightness_median'):.3f}**" for m in (p, n))),
        ("POVs whose 4 nearest neighbours are their true neighbours, 2-D before → after", "–",
         *(f"{m('quality.2d.before.neighbours_true_fraction'):.2f} → "
           f"{m('quality.2d.after.neighbours_true_fraction'):.2f}" for m in (p, n))),
        ("changes compensated / `sense` calls / motor states probed per POV (mean, max)", "–",
         "–", f"{n('exploration.compensated'):,} / {n('naive.calls_total'):,} / "
              f"{n('naive.queries_per_pov'):,.0f}, {n('naive.queries_per_pov_max'):,}"),
    ]
    lines = [HEADER, "|---|---|---|---|", *("| " + " | ".join(row) + " |" for row in rows)]
    return "\n".join(lines) + "\n"


def table_span(text: str) -> tuple[int, int]:
    """Start and end (character offsets) of the README's result table."""
    start = text.index(HEADER)
    end = start
    for line in text[start:].splitlines(keepends=True):
        if not line.startswith("|"):
            break
        end += len(line)
    return start, end


def rendered_readme(results: Path = RESULTS, readme: Path = README) -> tuple[str, str]:
    """(the README as it is, the README with its table rendered from ``results``)."""
    text = readme.read_text()
    paper, naive = (json.loads(metrics_path(s, results).read_text()) for s in STRATEGIES)
    start, end = table_span(text)
    return text, text[:start] + render(paper, naive) + text[end:]


def run_strategies(results: Path = RESULTS) -> None:
    """``sensorispace reproduce`` of both strategies; keeps their metrics.json."""
    for strategy in STRATEGIES:
        with tempfile.TemporaryDirectory() as out:
            subprocess.run([sys.executable, "-m", "sensorispace_ros.cli", "reproduce",
                            "--strategy", strategy, "--config", str(CONFIG), "--seed", "0",
                            "--no-figures", "--quiet", "--out", out], check=True, cwd=REPO)
            target = metrics_path(strategy, results)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(Path(out) / "metrics.json", target)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--render", action="store_true",
                      help="render only, from docs/readme-metrics/")
    mode.add_argument("--check", action="store_true", help="exit 1 if the README differs")
    args = parser.parse_args(argv)
    if not (args.render or args.check):
        run_strategies()
    before, after = rendered_readme()
    if args.check:
        if before != after:
            print("README.md's result table differs from docs/readme-metrics/: run "
                  "scripts/readme_results.py", file=sys.stderr)
            return 1
        return 0
    README.write_text(after)
    print(f"README.md's result table rendered from {RESULTS}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
