"""The simulated body's imperfections (core.imperfections, docs/bodies.md):
each does what its parameter says, measured against the perfect body; the
defaults are the perfect body bit for bit; the noise depends on the seed and
on the command's or the change's number only, so the offline driver and the
body node (which numbers them as the graph does) sense alike."""
from __future__ import annotations

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.config import ConfigError
from sensorispace_ros.core import retina
from sensorispace_ros.core.body import SensingOnly, simulate
from sensorispace_ros.core.paper.exploration import PAPER_PARAMS, build_world

MOTOR = np.random.default_rng(5).uniform(-3, 3, (50, 4))


def _world(seed=0, **imperfect):
    return build_world(seed, {"grid_count": 4, **imperfect})


def _pair(**imperfect):
    """A perfect and an imperfect body of the same world, at its first lights."""
    perfect, noisy = _world(), _world(**imperfect)
    return (perfect.body(lights=perfect.initial_lights), noisy.body(lights=noisy.initial_lights))


def test_the_defaults_are_the_perfect_body_bit_for_bit():
    world = _world()
    body = world.body(lights=world.initial_lights)
    assert body.noise is None and world.imperfections.perfect
    sensations, poses = body.sense_with_poses(MOTOR)
    pose = world.arm.forward(MOTOR)
    assert sensations.dtype == np.float64
    # Bit for bit against the perfect body's own kernel; NumPy's path agrees to
    # an ulp where its SIMD exp is not the C library's (core/numpy_math.py).
    raw, _ = simulate(MOTOR, world.initial_lights, world.receptors, body.kernel, world.arm)
    assert sensations.tobytes() == raw.tobytes()
    np.testing.assert_allclose(sensations, retina.sensation(pose, world.initial_lights,
                                                            world.receptors), rtol=1e-15, atol=0)
    assert poses.tobytes() == pose.tobytes()
    np.testing.assert_array_equal(body.motor_state, MOTOR[-1])
    rest, rest_pose = body.sense_at_rest()
    assert rest.tobytes() == sensations[-1].tobytes() and rest_pose.tobytes() == pose[-1].tobytes()


def test_an_imperfect_world_draws_the_same_world():
    perfect, noisy = _world(), _world(retina_noise=1e-3, motor_noise=1e-3, retina_dropout=0.1)
    for name in ("receptors", "initial_offsets", "grid", "m0"):
        np.testing.assert_array_equal(getattr(perfect, name), getattr(noisy, name))
    np.testing.assert_array_equal([e.center for e in perfect.events],
                                  [e.center for e in noisy.events])


def test_receptor_noise_has_the_sd_asked_for_and_comes_before_the_code():
    rows = np.repeat(MOTOR[:1], 20_000, axis=0)
    perfect, noisy = _pair(retina_noise=1e-3)
    difference = noisy.sense(rows) - perfect.sense(rows)
    assert abs(difference.std() / 1e-3 - 1) < 0.02 and abs(difference.mean()) < 3e-5
    # Before the code: a code that scales by 10 scales the noise too.
    scaled = _world(retina_noise=1e-3, code="scale", code_value=10.0)
    body = scaled.body(lights=scaled.initial_lights)
    assert abs((body.sense(rows) - 10 * perfect.sense(rows)).std() / 1e-2 - 1) < 0.02


def test_the_quantum_rounds_what_reaches_the_agent_after_the_code():
    perfect, quantised = _pair(retina_quantum=1e-2, code="scale", code_value=3.0)
    exact = 3.0 * perfect.sense(MOTOR)
    got = quantised.sense(MOTOR)
    steps = got / 1e-2
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert np.all(np.abs(got - exact) <= 0.5e-2 + 1e-12)
    assert len(np.unique(np.round(steps))) < len(np.unique(exact))


def test_float32_sensations_are_the_float64_ones_cast():
    perfect, narrow = _pair(retina_dtype="float32")
    got = narrow.sense(MOTOR)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, perfect.sense(MOTOR).astype(np.float32))
    assert narrow.sense_at_rest()[0].dtype == np.float32
    # The naive agent's view is float64 (as messages hands it in the graph).
    assert SensingOnly(narrow).sense(MOTOR).dtype == np.float64


def test_dropout_loses_whole_rows_at_the_rate_asked_for():
    perfect, lossy = _pair(retina_dropout=0.2)
    rows = np.repeat(MOTOR, 400, axis=0)                        # 20,000 rows
    got, exact = lossy.sense(rows), perfect.sense(rows)
    lost = np.isnan(got).any(axis=1)
    assert np.isnan(got[lost]).all()
    np.testing.assert_array_equal(got[~lost], exact[~lost])
    sd = np.sqrt(0.2 * 0.8 / len(rows))
    assert abs(lost.mean() - 0.2) < 4 * sd


def test_motor_noise_moves_the_arm_off_the_command_and_ground_truth_is_where_it_went():
    world = _world(motor_noise=1e-3)
    body = world.body(lights=world.initial_lights)
    rows = np.repeat(MOTOR[:1], 5000, axis=0)
    sensations, poses = body.sense_with_poses(rows)
    reached = body.last_reached
    error = reached - rows
    assert abs(error.std() / 1e-3 - 1) < 0.03 and np.all(error.std(axis=0) > 0)
    # Everything the body reports is of the joints reached, not of the command.
    np.testing.assert_array_equal(poses, world.arm.forward(reached))
    raw, _ = simulate(reached, world.initial_lights, world.receptors, body.kernel, world.arm)
    np.testing.assert_array_equal(sensations, raw)
    assert not np.allclose(poses, world.arm.forward(rows), atol=1e-6)
    np.testing.assert_array_equal(body.motor_state, reached[-1])
    np.testing.assert_array_equal(body.sense_at_rest()[1], world.arm.forward(reached[-1:])[0])
    # The evaluator replays the reached joints of any command from its number.
    np.testing.assert_array_equal(body.noise.reached(rows, 0), reached)
    body.move(MOTOR[:3])
    np.testing.assert_array_equal(body.motor_state, body.noise.reached(MOTOR[:3], 1)[-1])
    assert body.calls == 2


IMPERFECT = {"retina_noise": 1e-3, "retina_quantum": 1e-4, "retina_dtype": "float32",
             "retina_dropout": 0.05, "motor_noise": 1e-3}


def test_the_noise_is_the_seeds_and_each_commands_own():
    def body(seed):
        world = _world(seed, **IMPERFECT)
        return world.body(lights=world.initial_lights)

    first, again, other = body(0), body(0), body(1)
    a = [first.sense(MOTOR), first.sense(MOTOR)]
    assert a[0].tobytes() != a[1].tobytes()                     # each call draws anew
    # The same seed, the same noise, even with passive sensations in between
    # (they are numbered by change, commands by command).
    b0 = again.sense(MOTOR)
    again.sense_at_rest()
    again.set_lights(again.lights_world)
    again.sense_at_rest()
    again.set_lights(again.lights_world, change=0)
    assert again.sense(MOTOR).tobytes() == a[1].tobytes() and b0.tobytes() == a[0].tobytes()
    assert other.sense(MOTOR).tobytes() != a[0].tobytes()


def test_the_graph_numbering_senses_as_the_offline_driver():
    """The offline driver: set_lights per change, the agent's sense and move in
    order. The body node: set_lights(change=k), sense_at_rest(change=k), and a
    command sent twice answered under its first number."""
    world = _world(**IMPERFECT)
    offline, node = world.body(lights=world.initial_lights), world.body()
    node.set_lights(world.initial_lights, change=0)
    assert node.sense_at_rest(change=0)[0].tobytes() == offline.sense_at_rest()[0].tobytes()
    seen_offline, seen_node = [], []
    for k, event in enumerate(world.events[:3], start=1):
        offline.set_lights(event.lights)
        node.set_lights(event.lights, change=k)
        seen_offline.append(offline.sense_at_rest(kernel="numpy")[0])
        seen_node.append(node.sense_at_rest(change=k)[0])
        seen_offline.append(offline.sense(MOTOR[:5] + k))
        seen_node.append(node.sense_with_poses(MOTOR[:5] + k)[0])
        offline.move(MOTOR[5:6])
        first = node.sense_with_poses(MOTOR[5:6])[0]
        again = node.sense_with_poses(MOTOR[5:6], call=node.calls - 1)[0]   # re-sent
        seen_offline.append(offline.sense(MOTOR[6:9]))
        seen_node.append(node.sense_with_poses(MOTOR[6:9])[0])
        assert again.tobytes() == first.tobytes()
    for a, b in zip(seen_offline, seen_node):
        assert a.tobytes() == b.tobytes()
    assert offline.calls == node.calls
    np.testing.assert_array_equal(offline.motor_state, node.motor_state)


@pytest.mark.parametrize("section, name, value", [
    ("world.retina", "noise", -1e-3), ("world.retina", "quantum", -1.0),
    ("world.retina", "dtype", "int8"), ("world.retina", "dropout", 1.0),
    ("world.retina", "dropout", -0.1), ("arm", "motor_noise", float("nan")),
    ("arm", "motor_noise", -1e-4)])
def test_a_bad_imperfection_names_its_parameter(section, name, value):
    overrides: dict = {}
    node = overrides
    for part in section.split("."):
        node = node.setdefault(part, {})
    node[name] = value
    with pytest.raises(ConfigError, match=rf"{section}\.{name}:"):
        config.load_config(overrides=overrides)


def test_the_noisy_smoke_config_sets_every_imperfection():
    from pathlib import Path
    cfg = config.load_config(Path(__file__).resolve().parents[2] / "config" / "noisy-smoke.yaml")
    retina_cfg = cfg["world"]["retina"]
    assert (retina_cfg["noise"], retina_cfg["quantum"], retina_cfg["dtype"],
            retina_cfg["dropout"], cfg["arm"]["motor_noise"]) == (1e-3, 1e-3, "float32", 1e-3, 1e-3)
    smoke = config.load_config(Path(__file__).resolve().parents[2] / "config" / "smoke.yaml")
    assert cfg["world"]["grid_count"] == smoke["world"]["grid_count"]


def test_the_perfect_parameters_are_the_world_defaults():
    assert {key: PAPER_PARAMS[key] for key in IMPERFECT} == {
        "retina_noise": 0.0, "retina_quantum": 0.0, "retina_dtype": "float64",
        "retina_dropout": 0.0, "motor_noise": 0.0}
