"""The graph in a world on its own clock (docs/clock.md, the graph section).

``rows``: the body node is the row clock the offline driver plays
(``core.world_clock``), the agent node runs the clocked agent
(``core.clocked_run``'s reactions over the topics) and nothing announces a
change: the graph makes every call the offline run makes, so every metric
of the offline evaluation (``evaluation.naive``, ``evaluation.clock``) is
the same, the representation too. ``wall``: the environment changes on a
timer whatever the agent does; the run ends by itself and is evaluated.
"""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.graph import in_process

from shared import SMOKE, SMOKE_ROW_CLOCK, SMOKE_WALL_CLOCK

pytestmark = [pytest.mark.graph, pytest.mark.slow]

# Metrics that time the run, not what it did.
TIMED = ("timings", "seconds", "_s")


def _config(tmp_path, overrides, source=SMOKE):
    cfg = config.load_config(source, overrides=overrides)
    path = tmp_path / "clock.yaml"
    path.write_text(config.to_parameter_file(cfg))
    return cfg, path


def _graph(tmp_path, domain_id, path):
    seen = {}

    def keep(nodes, replace):
        seen.update(nodes)
    result = in_process.run_graph_in_process(path, domain_id, tmp_path / "run", timeout_s=900,
                                             on_spin=keep)
    return result, seen


def _evaluated(result, world):
    from sensorispace_ros.evaluation.clock import clock_metrics
    from sensorispace_ros.evaluation.naive import evaluate_naive_run
    metrics = dict(evaluate_naive_run(result, world).metrics)
    metrics.update(clock_metrics(result, world))
    return {k: v for k, v in metrics.items() if not any(t in k for t in TIMED)}


def test_the_graph_on_the_row_clock_gives_the_offline_metrics(tmp_path, domain_id):
    from sensorispace_ros.core.clocked_run import run_on_clock
    from sensorispace_ros.core.naive.params import NaiveParams
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.evaluation.graph_clock import graph_clocked_run
    from sensorispace_ros.core.world_clock import clock_events

    cfg, path = _config(tmp_path, SMOKE_ROW_CLOCK)
    world = run_world(cfg)
    offline = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows",
                           interval=cfg["world"]["change_interval"])
    result, nodes = _graph(tmp_path, domain_id, path)
    agent_node, body_node = nodes["agent"], nodes["body"]
    # Nothing announced a change: no passive sensation, no settle but the end's.
    assert agent_node.last_passive == -1 and not agent_node.passive
    graph = graph_clocked_run(agent_node.clock_run, world, clock_events(world, cfg),
                              clocked_body=body_node.clocked_body,
                              rows_after=body_node.rows_after)
    assert offline.clock.undone > 0 and offline.clock.held_rows > 0   # the clock did cut in
    agent, off = graph.agent, offline.agent
    assert (agent.queries_total, agent.calls_total) == (off.queries_total, off.calls_total)
    np.testing.assert_array_equal(graph.povs, offline.povs)
    np.testing.assert_array_equal(graph.pairs, offline.pairs)
    np.testing.assert_array_equal(graph.set_ids, offline.set_ids)
    assert body_node.clocked_body.row == offline.clock.rows
    assert body_node.clocked_body.held_rows == offline.clock.held_rows
    # A hold is one message however many rows it lasts: one per idle wait the
    # offline driver logged, and the last, answered with the end.
    view = agent_node.clock_view
    waits = sum(1 for kind in offline.clock.log.kind if kind == "hold")
    assert view.ended and view.holds == waits + 1
    assert offline.clock.held_rows > 100 * view.holds
    graph_metrics, offline_metrics = _evaluated(graph, world), _evaluated(offline, world)
    assert graph_metrics == offline_metrics
    assert graph_metrics["naive.clock.recall"] == 1.0 and graph_metrics[
        "naive.accepted_across_change"] == 0
    # What the representation node built is of these POVs and equality sets.
    arrays = result["nodes"]["representation"].result
    np.testing.assert_array_equal(arrays["povs"], offline.povs)
    np.testing.assert_array_equal(arrays["pairs"], offline.pairs)
    print({k: graph_metrics[k] for k in ("naive.clock.recall", "naive.clock.reactions",
                                         "naive.clock.undone_reactions")})


def test_the_graph_on_the_wall_clock_ends_by_itself_and_is_evaluated(tmp_path, domain_id):
    from sensorispace_ros.core.run_world import run_world
    from sensorispace_ros.evaluation.graph_clock import graph_clocked_run
    from sensorispace_ros.core.world_clock import clock_events

    # The agent shares the cores with whatever else runs: at a period it cannot
    # keep up with, the world moves on before it walks a POV.
    cfg, path = _config(tmp_path, {**SMOKE_WALL_CLOCK, "world.change_period_s": 0.3})
    world = run_world(cfg)
    result, nodes = _graph(tmp_path, domain_id, path)
    agent_node, body_node, environment = nodes["agent"], nodes["body"], nodes["environment"]
    assert agent_node.last_passive == -1 and environment.run_complete
    graph = graph_clocked_run(agent_node.clock_run, world, clock_events(world, cfg),
                              state_after=body_node.state_after)
    metrics = _evaluated(graph, world)
    # Measured, not reproducible: the world changed under the agent and it told.
    assert metrics["naive.clock.detections"] > 0 and metrics["naive.clock.tests"] > 0
    assert metrics["naive.accepted_across_change"] == 0
    assert len(graph.povs) >= 4
    assert result["nodes"]["representation"].result["povs"].shape == graph.povs.shape
    print({k: metrics[k] for k in sorted(metrics) if k.startswith(("naive.clock.", "naive.cov",
                                                                    "exploration.", "pov."))})
