"""core.scene: the viewer's geometry agrees with the arm's forward model and the
retina's projection, and its colours order positions."""
import numpy as np
import pytest

from sensorispace_ros.core import arm, retina, scene


@pytest.fixture
def rng():
    return np.random.default_rng(3)


def test_the_arm_is_drawn_from_the_base_to_the_forward_models_tip(rng):
    for motor in rng.uniform(-np.pi, np.pi, size=(20, 4)):
        joints = scene.arm_joint_positions(motor)
        assert joints.shape == (4, 2)
        np.testing.assert_array_equal(joints[0], [0.0, 0.0])
        np.testing.assert_allclose(np.linalg.norm(np.diff(joints, axis=0), axis=1),
                                   arm.SEGMENT_LENGTHS, atol=1e-12)
        np.testing.assert_allclose(joints[-1], arm.forward(motor)[:2], atol=1e-12)


def test_a_light_on_a_receptors_ray_projects_onto_that_receptor(rng):
    receptors = np.array([-0.9, -0.2, 0.4, 0.95])
    for pose in np.column_stack([rng.uniform(-3, 3, (10, 2)), rng.uniform(-4, 4, 10)]):
        segments = scene.eye_rays(pose, receptors, length=5.0).reshape(-1, 2, 2)
        np.testing.assert_allclose(segments[:, 0], np.tile(pose[:2], (len(receptors), 1)))
        np.testing.assert_allclose(np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1), 5.0)
        projection, _, visible = retina.project(pose, segments[:, 1])
        assert visible.all()
        np.testing.assert_allclose(projection, receptors, atol=1e-12)


def test_position_colours_grow_red_with_x_and_green_with_y():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [1.0, 2.0], [0.5, 1.0]])
    colours = scene.position_colours(xy)
    assert colours.shape == (5, 3) and colours.min() >= 0.0 and colours.max() <= 1.0
    np.testing.assert_allclose(colours[:, 0], [0, 1, 0, 1, 0.5])
    np.testing.assert_allclose(colours[:, 1], [0, 0, 1, 1, 0.5])
    assert scene.position_colours(np.zeros((0, 2))).shape == (0, 3)
    # all at one place: no division by a zero span
    assert np.isfinite(scene.position_colours(np.ones((3, 2)))).all()


def make_scene():
    return scene.Scene(np.linspace(-1, 1, 6), retina_half_width=1.0, ray_length=6.0)


def test_a_scene_draws_only_what_it_has_heard_of():
    view = make_scene()
    assert view.shapes() == []
    view.set_motor_state([0.1, -1.5, 2.2, -3.0])
    assert [s.namespace for s in view.shapes()] == ["arm", "joints", "field_of_view",
                                                    "receptors"]
    view.set_lights(np.array([[4.0, 1.0], [5.0, -2.0]]))
    view.add_points_of_view(np.array([7, 2]), np.array([[0.0] * 4, [0.3, 0.2, 0.1, 0.0]]))
    view.set_probes(np.array([[1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [2.0, 2.0, 0.5]]))
    shapes = {s.namespace: s for s in view.shapes()}
    assert set(shapes) == {"arm", "joints", "field_of_view", "receptors", "lights",
                           "points_of_view", "probes"}
    assert len(shapes["field_of_view"].points) == 4            # two edges of the retina
    assert len(shapes["receptors"].points) == 12                # one ray per receptor
    np.testing.assert_allclose(shapes["lights"].points[:, :2], [[4, 1], [5, -2]])
    np.testing.assert_allclose(shapes["points_of_view"].points[:, :2],
                               arm.forward(np.array([[0.3, 0.2, 0.1, 0.0], [0.0] * 4]))[:, :2])
    assert all(np.all(s.points[:, 2] == 0) for s in shapes.values())  # the arm is planar


def test_the_representation_is_coloured_by_true_position_and_grey_when_unknown():
    view = make_scene()
    motor = np.array([[0.0, 0.0, 0.0, 0.0], [np.pi / 2, 0.0, 0.0, 0.0]])   # x=3 and y=3
    view.add_points_of_view(np.array([10, 20]), motor)
    colours = view.representation_colours(np.array([20, 10, 99]))
    np.testing.assert_allclose(colours[0], [0.0, 1.0, 0.5], atol=1e-12)   # smallest x
    np.testing.assert_allclose(colours[1], [1.0, 0.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(colours[2], scene.UNKNOWN_POSITION_COLOUR)


def test_bad_shapes_and_motor_states_are_refused_by_name():
    with pytest.raises(ValueError, match="kind"):
        scene.Shape("x", "cubes", np.zeros((1, 3)), 1.0, (1, 1, 1, 1))
    with pytest.raises(ValueError, match="points"):
        scene.Shape("x", scene.LINE_LIST, np.zeros((3, 3)), 1.0, (1, 1, 1, 1))
    with pytest.raises(ValueError, match="motor_state"):
        scene.arm_joint_positions([0.0, 1.0])
    with pytest.raises(ValueError, match="ray_length"):
        scene.Scene(np.zeros(3), 1.0, 0.0)


@pytest.mark.parametrize("body_arm", [arm.Arm(segments=(1.5, 0.5)),
                                      arm.Arm(segments=(1.0, 0.7, 0.6, 0.4), eye="link",
                                              unit="deg")])
def test_any_planar_chain_is_drawn_from_its_base_to_its_eye(rng, body_arm):
    view = scene.Scene(np.linspace(-1, 1, 6), 1.0, 6.0, body_arm=body_arm)
    period = 360.0 if body_arm.unit == "deg" else 2 * np.pi
    motor = rng.uniform(-period / 2, period / 2, size=(5, body_arm.n_joints))
    for state in motor:
        joints = scene.arm_joint_positions(state, body_arm)
        assert joints.shape == (body_arm.n_links + 1, 2)
        np.testing.assert_allclose(np.linalg.norm(np.diff(joints, axis=0), axis=1),
                                   body_arm.segments, atol=1e-12)
        np.testing.assert_allclose(joints[-1], body_arm.forward(state)[:2], atol=1e-12)
    view.set_motor_state(motor[0])
    view.add_points_of_view(np.array([3, 1]), motor[1:3])
    shapes = {s.namespace: s for s in view.shapes()}
    np.testing.assert_allclose(shapes["arm"].points[-1, :2], body_arm.forward(motor[0])[:2])
    np.testing.assert_allclose(shapes["points_of_view"].points[:, :2],
                               body_arm.forward(motor[[2, 1]])[:, :2])
    with pytest.raises(ValueError, match=f"must hold {body_arm.n_joints} joint angles"):
        view.set_motor_state(np.zeros(body_arm.n_joints + 1))
