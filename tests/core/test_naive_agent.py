"""The naive agent: only ``sense`` in, checked against ground truth outside it."""
import ast
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from sensorispace_ros.core import arm, retina
from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import run_naive
from sensorispace_ros.core.world import REDISTRIBUTION
from sensorispace_ros.evaluation.naive import evaluate_naive_run

from naive_flag_runs import assert_same_results, runs_on_and_off

PACKAGE = Path(__file__).resolve().parents[2] / "sensorispace_ros"
NAIVE = PACKAGE / "core" / "naive"
# The agent's own modules; core/naive/run.py drives it against the simulator.
NAIVE_MODULES = ("agent", "anchors", "compensation", "equality_sets", "jacobians", "loop_walk",
                 "noise", "points_of_view", "searching", "sense_memory", "structure",
                 "surface")
# Modules that know the arm, the retina, the lights or the events.
GROUND_TRUTH = ("sensorispace_ros.core.arm", "sensorispace_ros.core.retina",
                "sensorispace_ros.core.world", "sensorispace_ros.core.body",
                "sensorispace_ros.core.paper", "sensorispace_ros.core.naive.run",
                "sensorispace_ros.offline")


def _knows_ground_truth(module: str) -> bool:
    return any(module == g or module.startswith(g + ".") for g in GROUND_TRUTH)


def _imported_modules(path: Path) -> set:
    """Every module a file imports, as absolute dotted names."""
    package = "sensorispace_ros." + ".".join(path.relative_to(PACKAGE).parent.parts)
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return names


def test_the_ground_truth_check_sees_a_ground_truth_import():
    imported = _imported_modules(PACKAGE / "core" / "naive" / "run.py")
    assert any(_knows_ground_truth(m) for m in imported)


@pytest.mark.parametrize("module", NAIVE_MODULES)
def test_naive_modules_import_no_ground_truth(module):
    imported = _imported_modules(NAIVE / f"{module}.py")
    assert not [m for m in imported if _knows_ground_truth(m)]


def test_loading_the_agent_loads_no_ground_truth_module():
    code = ("import sys, sensorispace_ros.core.naive.agent\n"
            "print(' '.join(m for m in sys.modules if m.startswith('sensorispace_ros.')))")
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True, cwd=PACKAGE.parent).stdout.split()
    assert "sensorispace_ros.core.naive.agent" in loaded
    assert not [m for m in loaded if _knows_ground_truth(m)]


class ClosureBody:
    """Builds a body that is nothing but a closure over the simulator's sense,
    and remembers the last row it was sent (where the arm rests)."""

    def __init__(self):
        self.last_row = None

    def __call__(self, simulator: SimulatedBody):
        def sense(motor_states):
            motor_states = np.asarray(motor_states, dtype=float)
            self.last_row = motor_states[-1].copy()
            return simulator.sense(motor_states)
        return types.SimpleNamespace(sense=sense, n_motors=4, n_sensors=6)


@pytest.fixture(scope="module")
def small_run():
    world = build_world(0, {"grid_count": 12})
    wrapper = ClosureBody()
    result = run_naive(world, NaiveParams(), body_wrapper=wrapper)
    evaluated = evaluate_naive_run(result, world, paper_positions=np.zeros((0, 2)))
    return world, result, evaluated, wrapper


def test_compensations_are_true_and_never_on_state_changes(small_run):
    _, result, evaluated, _ = small_run
    m = evaluated.metrics
    assert m["naive.compensations_accepted"] > 10
    assert m["naive.wrong_poses"] == 0 and m["naive.worst_pose_error"] < 1e-6
    assert m["naive.state_changes_accepted"] == 0
    assert m["naive.accepted_across_redistribution"] == 0
    assert m["exploration.state_changes"] > 0        # there were some to refuse
    # Every POV is a spatial relative of the start: same eye orientation.
    assert m["naive.max_orientation_error"] < 1e-6
    assert m["pov.max_pose_drift"] < 1e-6
    assert m["naive.duplicate_povs"] == 0
    # The object's grid position when each POV was found; the start's is none.
    assert evaluated.grid_index[0] == -1 and np.all(evaluated.grid_index[1:] >= 0)
    assert len(evaluated.grid_index) == len(result.povs) == len(evaluated.true_poses)


def test_equality_sets_are_true_equal_displacements(small_run):
    _, result, evaluated, _ = small_run
    assert evaluated.metrics["naive.equality_sets"] > 5
    assert evaluated.metrics["naive.equality_set_max_deviation"] < 1e-6
    pairs, set_ids = result.pairs, result.set_ids
    assert pairs.shape == (len(set_ids), 2) and np.all(pairs[:, 0] != pairs[:, 1])
    assert pairs.max() < len(result.povs)


def test_agent_ends_every_reaction_resting_where_it_says(small_run):
    world, _, _, _ = small_run
    wrapper = ClosureBody()
    simulator = SimulatedBody(world.receptors, world.initial_lights)
    agent = NaiveAgent(wrapper(simulator), NaiveParams())
    reaction = agent.start(world.m0)
    np.testing.assert_array_equal(wrapper.last_row, world.m0)
    assert reaction.new_povs.shape == (1, 100, 4) and list(reaction.new_pov_ids) == [0]
    for event, reaction in _drive(agent, simulator, world, world.events[:30]):
        np.testing.assert_array_equal(wrapper.last_row, reaction.rest_motor_state)
        assert reaction.equality_rows.shape[1] == 3
        assert reaction.queries > 0 and reaction.calls > 0
        if event.kind == REDISTRIBUTION:
            assert not reaction.compensated


def test_same_world_same_run():
    world = build_world(1, {"grid_count": 8, "order": "tracking"})
    first = run_naive(world, NaiveParams())
    second = run_naive(world, NaiveParams())
    np.testing.assert_array_equal(first.povs, second.povs)
    np.testing.assert_array_equal(first.pairs, second.pairs)
    assert first.agent.queries_total == second.agent.queries_total


def test_tracking_schedule_compensates_correctly():
    world = build_world(2, {"grid_count": 10, "order": "tracking"})
    result = run_naive(world, NaiveParams())
    m = evaluate_naive_run(result, world, paper_positions=np.zeros((0, 2))).metrics
    assert m["exploration.compensated"] > 10
    assert m["naive.wrong_poses"] == 0 and m["naive.state_changes_accepted"] == 0


def _drive(agent, simulator, world, events):
    for event in events:
        simulator.set_lights(event.lights)
        passive = retina.sensation(arm.forward(simulator.motor_state), event.lights,
                                   world.receptors)
        yield event, agent.react(passive)


def test_equality_pass_adds_sets_and_no_points_of_view():
    world = build_world(3, {"grid_count": 10})
    simulator = SimulatedBody(world.receptors, world.initial_lights)
    agent = NaiveAgent(ClosureBody()(simulator), NaiveParams())
    agent.start(world.m0)
    for _ in _drive(agent, simulator, world, world.events):
        pass
    n_povs, n_sets = len(agent.points_of_view), len(np.unique(agent.equality_sets()[1]))
    assert n_povs > 5
    simulator.set_lights(world.initial_lights)
    agent.begin_equality_pass()
    true_xy = arm.forward(agent.points_of_view[:, 0])[:, :2]
    for _, reaction in _drive(agent, simulator, world, world.events):
        assert len(reaction.new_pov_ids) == 0
        rows = reaction.equality_rows
        if len(rows):
            moved = true_xy[rows[:, 2]] - true_xy[rows[:, 1]]
            assert np.max(np.abs(moved - moved[0])) < 1e-6
    assert len(agent.points_of_view) == n_povs
    assert len(np.unique(agent.equality_sets()[1])) > n_sets


@pytest.mark.parametrize("name, value", [("fd_step", 0.0), ("lm_restarts", 0),
                                         ("match_tol", 1.0), ("pov_initial_step", 1.0),
                                         ("max_snapshots", 2.5), ("min_singular", -1.0),
                                         ("lm_initial_damping", 0.0),
                                         ("remember_split_povs", "yes")])
def test_bad_parameters_are_named(name, value):
    with pytest.raises(ValueError, match=rf"^naive\.{name}:"):
        NaiveParams(**{name: value})


def test_unknown_parameter_is_named():
    with pytest.raises(ValueError, match=r"^naive\.batch: unknown"):
        NaiveParams.from_mapping({"batch": 3})
    assert NaiveParams.from_mapping({"lm_restarts": 3}).lm_restarts == 3


def test_agent_calls_out_of_order_and_bad_inputs():
    body = types.SimpleNamespace(sense=lambda m: np.zeros((len(m), 6)), n_motors=4, n_sensors=6)
    agent = NaiveAgent(body)
    with pytest.raises(RuntimeError, match="before start"):
        agent.react(np.zeros(6))
    with pytest.raises(ValueError, match="initial_motor_state"):
        agent.start([0.0, 1.0])
    with pytest.raises(ValueError, match="body"):
        NaiveAgent(types.SimpleNamespace(sense=None, n_motors=4, n_sensors=6))
    reaction = agent.start(np.zeros(4))
    # A blank world: no POV can be sampled, but the agent still rests somewhere.
    assert len(reaction.new_pov_ids) == 0
    with pytest.raises(ValueError, match="passive_sensation"):
        agent.react(np.zeros(5))
    assert not agent.react(np.zeros(6)).compensated


def test_remembered_split_povs_change_no_result_only_the_walks():
    on, off = runs_on_and_off("remember_split_povs", grid_count=16)
    assert assert_same_results(on, off) > 10
    split = on.agent.split_motor_states
    assert len(split) > 0 and len(off.agent.split_motor_states) == 0
    assert on.agent.split_walks_skipped > 0 and off.agent.split_walks_skipped == 0
    assert on.agent.calls_by_stage["pov"] < off.agent.calls_by_stage["pov"]
    # Ground truth: each remembered state is a different loop (none was walked
    # twice), and none is the loop of a valid POV.
    poses = arm.forward(split)
    gap = np.linalg.norm(poses[:, None, :2] - poses[None, :, :2], axis=-1)
    assert np.min(gap + np.eye(len(split))) > 1e-3
    pov_poses = arm.forward(on.povs[:, 0])
    assert np.min(np.linalg.norm(poses[:, None, :2] - pov_poses[None, :, :2], axis=-1)) > 1e-3


def test_the_lattice_adds_true_sets_after_the_found_ones(small_run):
    # The run's sets are the agent's found sets, then the lattice's, numbered
    # after them; every implied set moves its POVs by one true displacement.
    _, result, evaluated, _ = small_run
    agent = result.exploration.agent
    found_pairs, found_ids = agent._found_sets()
    implied = agent.lattice_sets()
    assert implied.placed == len(result.povs) and len(implied.pairs) > len(found_pairs) / 10
    np.testing.assert_array_equal(result.pairs, np.vstack([found_pairs, implied.pairs]))
    assert result.set_ids[len(found_ids):].min() == found_ids.max() + 1
    positions = np.asarray(evaluated.true_poses)[:, :2]
    shift = positions[implied.pairs[:, 1]] - positions[implied.pairs[:, 0]]
    for s in np.unique(implied.set_ids):
        members = shift[implied.set_ids == s]
        assert np.abs(members - members[0]).max() < 1e-6
