"""The ``sensorispace`` command: errors are one line, compare shows differences,
every verb has its module."""
from __future__ import annotations

import argparse
import importlib
import json
import re

import pytest

from sensorispace_ros.cli import main as cli
from sensorispace_ros.cli.compare import compare_table

from shared import SMOKE


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
    text = compare_table(RUN_A, RUN_A)
    rows = rows_by_key(text)
    assert rows["exploration.compensated"].split()[1:] == ["648", "648"]
    for marker in ("%", "differs", "only in", "max |diff|"):
        assert marker not in text
    assert "same configuration" in text


# ---------------------------------------------------------------------------
# Verbs


def listed_verbs(capsys) -> list[str]:
    """The verbs ``sensorispace --help`` lists."""
    with pytest.raises(SystemExit) as caught:
        cli.main(["--help"])
    assert caught.value.code == 0
    usage = capsys.readouterr().out
    verbs = re.findall(r"^    ([a-z][\w-]*)", usage.split("COMMAND", 2)[2], re.M)
    assert verbs, usage
    return verbs


def test_every_listed_verb_has_its_module_and_handler(capsys):
    verbs = listed_verbs(capsys)
    assert {"reproduce", "compare", "launch", "analyze", "replay", "bag"} <= set(verbs)
    parser, _ = cli.build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for verb in verbs:
        module = importlib.import_module(f"sensorispace_ros.cli.{verb}")
        assert callable(module.add_arguments) and module.HELP and module.DESCRIPTION, verb
        handler = subparsers.choices[verb].get_default("handler")
        if handler is None:                     # a verb of actions: each has its handler
            actions = next(a for a in subparsers.choices[verb]._actions
                           if isinstance(a, argparse._SubParsersAction))
            handlers = [p.get_default("handler") for p in actions.choices.values()]
        else:
            handlers = [handler]
        assert handlers and all(h is not None and h.__module__ == module.__name__
                                for h in handlers), verb


def test_a_verbs_user_error_is_one_line(monkeypatch, capsys):
    from sensorispace_ros.cli import replay
    from sensorispace_ros.recording.bag_format import BagError

    def truncated(args: argparse.Namespace) -> int:
        raise BagError(f"{args.bag}: truncated\nsecond line")
    monkeypatch.setattr(replay, "run", truncated)
    assert cli.main(["replay", "x.mcap"]) == 2
    assert one_error_line(capsys.readouterr()) == "sensorispace: error: x.mcap: truncated second line"


def test_an_error_that_is_not_the_users_shows_its_traceback(monkeypatch):
    from sensorispace_ros.cli import compare

    def broken(args: argparse.Namespace) -> int:
        raise RuntimeError("a bug")
    monkeypatch.setattr(compare, "run", broken)
    with pytest.raises(RuntimeError, match="a bug"):
        cli.main(["compare", "a", "b"])


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
