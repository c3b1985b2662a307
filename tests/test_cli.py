"""The ``sensorispace`` command: errors are one line, compare shows differences,
subcommands of other modules plug in."""
from __future__ import annotations

import argparse
import json
import sys
import types
from pathlib import Path

import pytest

from sensorispace_ros.cli import main as cli

REPO = Path(__file__).resolve().parents[1]
SMOKE = REPO / "config" / "smoke.yaml"


def one_error_line(captured) -> str:
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err
    assert lines[0].startswith("sensorispace: error: ")
    return lines[0]


# ---------------------------------------------------------------------------
# Errors


def test_missing_config_file_is_one_line_and_exit_2(tmp_path, capsys):
    status = cli.main(["reproduce", "--config", str(tmp_path / "absent.yaml"),
                       "--out", str(tmp_path / "run"), "--quiet"])
    assert status == 2
    assert "absent.yaml" in one_error_line(capsys.readouterr())
    assert not (tmp_path / "run").exists()


def test_bad_config_value_names_the_parameter(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("/**:\n  ros__parameters:\n    world:\n      grid_count: 1\n")
    status = cli.main(["reproduce", "--config", str(path), "--out", str(tmp_path / "run"),
                       "--quiet"])
    assert status == 2
    line = one_error_line(capsys.readouterr())
    assert "world.grid_count: must be an integer >= 2, got 1" in line


def test_typo_in_config_is_an_error(tmp_path, capsys):
    path = tmp_path / "typo.yaml"
    path.write_text("/**:\n  ros__parameters:\n    pov:\n      n_sample: 50\n")
    assert cli.main(["reproduce", "--config", str(path), "--out", str(tmp_path / "r")]) == 2
    assert "pov.n_sample: unknown parameter" in one_error_line(capsys.readouterr())


def test_compare_with_a_missing_run_is_one_line(tmp_path, capsys):
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"pov": {"count": 1}}))
    assert cli.main(["compare", str(good), str(tmp_path / "nowhere")]) == 2
    assert "nowhere" in one_error_line(capsys.readouterr())


def test_compare_with_a_corrupt_metrics_file_is_one_line(tmp_path, capsys):
    good, bad = tmp_path / "good.json", tmp_path / "bad.json"
    good.write_text(json.dumps({"pov": {"count": 1}}))
    bad.write_text("{ not json")
    assert cli.main(["compare", str(good), str(bad)]) == 2
    assert "bad.json: not valid JSON" in one_error_line(capsys.readouterr())


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as caught:
        cli.main(["reproduce", "--strategy", "clever"])
    assert caught.value.code == 2
    assert "invalid choice" in capsys.readouterr().err
    with pytest.raises(SystemExit) as caught:
        cli.main(["reproduce", "--seed", "-3"])
    assert caught.value.code == 2


def test_debug_environment_variable_shows_the_traceback(tmp_path, monkeypatch):
    monkeypatch.setenv("SENSORISPACE_DEBUG", "1")
    from sensorispace_ros.config import ConfigError
    with pytest.raises(ConfigError):
        cli.main(["reproduce", "--config", str(tmp_path / "absent.yaml"), "--quiet"])


# ---------------------------------------------------------------------------
# compare


RUN_A = {
    "strategy": "paper", "seed": 0,
    "exploration": {"compensated": 648, "events": 4230},
    "quality": {"2d": {"after": {"affine_residual": 0.0004, "trustworthiness": 0.9995}}},
    "regularization": {"2d": {"set_spread": [0.5, 0.25]}},
    "timings_s": {"total": 80.0},
    "config": {"seed": 0, "world.grid_count": 62, "world.schedule": "random"},
}
RUN_B = {
    "strategy": "naive", "seed": 0,
    "exploration": {"compensated": 620, "events": 4230},
    "quality": {"2d": {"after": {"affine_residual": 0.0008, "trustworthiness": 0.9995}}},
    "regularization": {"2d": {"set_spread": [0.5, 0.125]}},
    "naive": {"coverage": 0.95},
    "timings_s": {"total": 120.0},
    "config": {"seed": 0, "world.grid_count": 62, "world.schedule": "tracking"},
}


def rows_by_key(text: str) -> dict[str, str]:
    return {line.split()[0]: line for line in text.splitlines() if line.strip()}


def test_compare_lists_both_values_and_the_difference(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "metrics.json").write_text(json.dumps(RUN_A))
    (tmp_path / "b.json").write_text(json.dumps(RUN_B))
    assert cli.main(["compare", str(tmp_path / "a"), str(tmp_path / "b.json")]) == 0
    out = capsys.readouterr().out
    rows = rows_by_key(out)
    compensated = rows["exploration.compensated"].split()
    assert compensated[1:4] == ["648", "620", "-28"]
    assert "-4.3 %" in rows["exploration.compensated"]          # -28 / 648
    assert rows["exploration.events"].split()[1:] == ["4230", "4230"]   # equal: no difference
    assert "+50.0 %" in rows["timings_s.total"]
    assert "+100.0 %" in rows["quality.2d.after.affine_residual"]
    assert "max |diff| 0.125" in rows["regularization.2d.set_spread"]
    assert "only in B" in rows["naive.coverage"]
    assert "differs" in rows["strategy"]
    # Configuration: only the parameter that differs is listed.
    config_part = out.split("configuration differences:")[1]
    assert "world.schedule" in config_part and "tracking" in config_part
    assert "world.grid_count" not in config_part


def test_compare_only_different_hides_equal_values(tmp_path, capsys):
    (tmp_path / "a.json").write_text(json.dumps(RUN_A))
    (tmp_path / "b.json").write_text(json.dumps(RUN_B))
    cli.main(["compare", "--only-different", str(tmp_path / "a.json"), str(tmp_path / "b.json")])
    rows = rows_by_key(capsys.readouterr().out)
    assert "exploration.events" not in rows
    assert "quality.2d.after.trustworthiness" not in rows
    assert "exploration.compensated" in rows


def test_compare_of_a_run_with_itself_shows_no_difference(tmp_path):
    text = cli.compare_table(RUN_A, RUN_A)
    rows = rows_by_key(text)
    assert rows["exploration.compensated"].split()[1:] == ["648", "648"]
    for marker in ("%", "differs", "only in", "max |diff|"):
        assert marker not in text
    assert "same configuration" in text


# ---------------------------------------------------------------------------
# Subcommands contributed by other modules


def test_missing_extension_modules_are_tolerated(monkeypatch):
    monkeypatch.setattr(cli, "EXTENSIONS", ("sensorispace_ros.no_such_module",))
    parser, errors = cli.build_parser()
    assert errors == ()
    assert parser.parse_args(["compare", "a", "b"]).handler is cli.run_compare


def test_extension_with_a_broken_import_is_not_hidden(monkeypatch, tmp_path):
    broken = tmp_path / "broken_extension.py"
    broken.write_text("import no_such_dependency_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(cli, "EXTENSIONS", ("broken_extension",))
    with pytest.raises(ModuleNotFoundError, match="no_such_dependency_xyz"):
        cli.build_parser()


def test_extension_registers_a_subcommand_and_its_user_errors(monkeypatch, capsys):
    class BagProblem(Exception):
        pass

    def register(subparsers):
        parser = subparsers.add_parser("probe")
        parser.add_argument("bag")

        def handler(args: argparse.Namespace) -> int:
            raise BagProblem(f"{args.bag}: truncated\nsecond line")
        parser.set_defaults(handler=handler)

    module = types.ModuleType("fake_extension")
    module.register, module.USER_ERRORS = register, (BagProblem,)
    monkeypatch.setitem(sys.modules, "fake_extension", module)
    monkeypatch.setattr(cli, "EXTENSIONS", ("fake_extension",))
    assert cli.main(["probe", "x.mcap"]) == 2
    assert one_error_line(capsys.readouterr()) == "sensorispace: error: x.mcap: truncated second line"


# ---------------------------------------------------------------------------
# reproduce end to end (smoke profile, no figures: the pipeline tests draw them)


def test_reproduce_writes_metrics_and_prints_a_summary(tmp_path, capsys):
    out = tmp_path / "run"
    status = cli.main(["reproduce", "--strategy", "paper", "--seed", "1", "--config", str(SMOKE),
                       "--out", str(out), "--no-figures", "--quiet"])
    assert status == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["seed"] == 1 and metrics["config"]["seed"] == 1
    assert metrics["config"]["output.figures"] is False
    assert not (out / "figures").exists()
    summary = capsys.readouterr().out
    assert "paper strategy, seed 1" in summary
    assert f"{metrics['exploration']['compensated']} compensated" in summary
    assert "2D after" in summary and "time (s)" in summary


# ---------------------------------------------------------------------------
# Progress display


class FakeClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class FakeTerminal:
    def __init__(self, tty: bool):
        self.text, self.tty = "", tty

    def write(self, text):
        self.text += text

    def flush(self):
        pass

    def isatty(self):
        return self.tty


def test_progress_in_a_log_prints_periodic_plain_lines_with_eta():
    from sensorispace_ros.progress import Progress

    clock, log = FakeClock(), FakeTerminal(tty=False)
    progress = Progress(stream=log, interval_s=10.0, clock=clock)
    with progress.stage("hausdorff", total=100):
        for done in range(1, 101):
            clock.now += 0.5                 # 50 s in all
            progress(done)
    lines = log.text.splitlines()
    assert "\r" not in log.text
    # one line per 10 s (at 10, 20, 30, 40 s), then the closing line
    assert len(lines) == 5, lines
    assert lines[0].startswith("[hausdorff]  20.0% elapsed 10.0s ETA 40.0s")
    assert lines[-1] == "[hausdorff] done in 50.0s"
    assert progress.durations["hausdorff"] == 50.0


def test_progress_on_a_terminal_rewrites_one_line():
    from sensorispace_ros.progress import Progress

    clock, terminal = FakeClock(), FakeTerminal(tty=True)
    progress = Progress(stream=terminal, clock=clock)
    with progress.stage("cca"):
        clock.now = 1.0
        progress(0.25)                       # a fraction when no total is given
        clock.now = 2.0
        progress(3, 4)
    assert terminal.text.count("\n") == 1    # only the closing line ends a line
    assert "\r[cca]  25.0% elapsed 1.0s ETA 3.0s" in terminal.text
    assert "\r[cca]  75.0% elapsed 2.0s ETA 0.7s" in terminal.text
    assert terminal.text.endswith("[cca] done in 2.0s\n")


def test_disabled_progress_is_silent():
    from sensorispace_ros.progress import Progress

    log = FakeTerminal(tty=False)
    progress = Progress(stream=log, enabled=False, interval_s=0.0)
    with progress.stage("x", total=2):
        progress(1)
    assert log.text == ""
