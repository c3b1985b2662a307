"""A MuJoCo model as a body: its eye, its joints, its object, and the planar
chain its kinematics describe (ground truth).

``MujocoSpec.load(cfg)`` reads ``mujoco.*``: the MJCF file, the camera that
is the eye, the hinge joints the agent commands and the mocap body the
environment moves. A name the model lacks stops it, naming the parameter and
listing what the model has.

Ground truth (``planar_chain``): where the commanded hinges turn about
parallel vertical axes and the eye rides the chain, MuJoCo's kinematics is a
planar chain (``core.arm.Arm``): the link lengths are the distances between
the hinges' anchors and from the last one to the camera; the eye turns with
a last hinge on its axis (``eye: joint``) or is fixed to the last link
(``eye: link``). The chain's frame has its base at the first hinge and its x
axis along the links at zero angles; the camera's pose in it is (x, y, the
heading of the image's x axis less its heading at zero angles). That
description is checked against MuJoCo's own kinematics at seeded random
joint states before a run uses it (the paper strategy, the compensable
positions and every POV's true pose are then computed with it).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensorispace_ros.bodies import mujoco_render  # noqa: F401  (MUJOCO_GL before mujoco)
from sensorispace_ros.config import ConfigError
from sensorispace_ros.core.arm import Arm, wrap_angle

REPO = Path(__file__).resolve().parents[2]
CHECK_STATES = 64           # seeded joint states the chain is checked at
CHECK_TOLERANCE = 1e-9      # relative to the chain's reach (positions), radians (headings)


def _names(model, kind, count: int, keep=lambda i: True) -> list[str]:
    import mujoco
    return [mujoco.mj_id2name(model, kind, i) or f"#{i}" for i in range(count) if keep(i)]


def model_path(name: str) -> Path:
    """The MJCF file ``mujoco.model`` names: absolute, or relative to the working
    directory, else to the repository."""
    if not name:
        raise ConfigError("mujoco.model: body.kind mujoco needs an MJCF file, got ''")
    path = Path(name).expanduser()
    for candidate in ([path] if path.is_absolute() else [Path.cwd() / path, REPO / path]):
        if candidate.is_file():
            return candidate
    raise ConfigError(f"mujoco.model: no such file {name!r} (looked in {Path.cwd()} and {REPO})")


@dataclass
class MujocoSpec:
    """The loaded model and the ids of what ``mujoco.*`` names."""

    path: Path
    model: object
    camera: int
    joints: tuple[int, ...]
    joint_names: tuple[str, ...]
    object_body: int
    object_geoms: tuple[int, ...]
    mocap: int

    @classmethod
    def load(cls, cfg: dict) -> "MujocoSpec":
        import mujoco

        params = cfg["mujoco"]
        path = model_path(params["model"])
        try:
            model = mujoco.MjModel.from_xml_path(str(path))
        except ValueError as error:
            raise ConfigError(f"mujoco.model: {path} is not a model MuJoCo loads: {error}") from None
        camera = _camera(model, params["camera"])
        body = _object(model, params["object"])
        joints = _joints(model, params["joints"], body)
        geoms = tuple(int(g) for g in np.flatnonzero(model.geom_bodyid == body))
        if not geoms:
            raise ConfigError(f"mujoco.object: body {params['object'] or '#' + str(body)!r} "
                              "has no geoms to see")
        names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints)
        return cls(path, model, camera, joints, names, body, geoms, int(model.body_mocapid[body]))


def _camera(model, name: str) -> int:
    import mujoco
    cameras = _names(model, mujoco.mjtObj.mjOBJ_CAMERA, model.ncam)
    if not name:
        if model.ncam != 1:
            raise ConfigError(f"mujoco.camera: must name the eye among the model's cameras "
                              f"({', '.join(cameras) or 'none'}), got ''")
        return 0
    camera = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
    if camera < 0:
        raise ConfigError(f"mujoco.camera: the model has no camera {name!r} "
                          f"(its cameras: {', '.join(cameras) or 'none'})")
    return int(camera)


def _object(model, name: str) -> int:
    import mujoco
    mocap = [b for b in range(model.nbody) if model.body_mocapid[b] >= 0]
    mocap_names = _names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody, lambda b: b in mocap)
    if not name:
        if len(mocap) != 1:
            raise ConfigError(f"mujoco.object: must name the object among the model's mocap "
                              f"bodies ({', '.join(mocap_names) or 'none'}), got ''")
        return mocap[0]
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if body < 0 or model.body_mocapid[body] < 0:
        raise ConfigError(f"mujoco.object: the model has no mocap body {name!r} (its mocap "
                          f"bodies: {', '.join(mocap_names) or 'none'})")
    return int(body)


def _joints(model, names: list[str], object_body: int) -> tuple[int, ...]:
    import mujoco
    hinge = mujoco.mjtJoint.mjJNT_HINGE

    def in_object(j):
        body = model.jnt_bodyid[j]
        while body > 0:
            if body == object_body:
                return True
            body = model.body_parentid[body]
        return False

    hinges = [j for j in range(model.njnt) if model.jnt_type[j] == hinge and not in_object(j)]
    hinge_names = _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt, lambda j: j in hinges)
    if not names:
        if not hinges:
            raise ConfigError("mujoco.joints: the model has no hinge joint outside the object")
        return tuple(hinges)
    if len(set(names)) != len(names):
        raise ConfigError(f"mujoco.joints: a joint is named twice, got {names!r}")
    out = []
    for name in names:
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if joint not in hinges:
            raise ConfigError(f"mujoco.joints: the model has no hinge joint {name!r} outside the "
                              f"object (its hinges: {', '.join(hinge_names) or 'none'})")
        out.append(int(joint))
    return tuple(out)


@dataclass(frozen=True)
class PlanarChain:
    """The chain MuJoCo's kinematics describe (``core.arm.Arm``) and where its
    frame lies in the world: ``base`` (x, y), ``heading`` (its x axis), and the
    camera's heading at zero angles in it (``eye_heading``)."""

    arm: Arm
    base: np.ndarray
    heading: float
    eye_heading: float

    def to_chain(self, world_poses: np.ndarray) -> np.ndarray:
        """World poses ``(B, 3)`` (x, y, the image's heading) in the chain's frame."""
        c, s = np.cos(self.heading), np.sin(self.heading)
        rel = world_poses[:, :2] - self.base
        return np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1],
                                world_poses[:, 2] - self.heading - self.eye_heading])

    def to_world_xy(self, xy: np.ndarray) -> np.ndarray:
        """Chain-frame positions ``(..., 2)`` in the world."""
        c, s = np.cos(self.heading), np.sin(self.heading)
        xy = np.asarray(xy, dtype=float)
        return self.base + np.stack([c * xy[..., 0] - s * xy[..., 1],
                                     s * xy[..., 0] + c * xy[..., 1]], axis=-1)


def camera_pose(data, camera: int) -> np.ndarray:
    """(x, y, heading of the image's x axis) of ``camera`` in the world."""
    xmat = data.cam_xmat[camera].reshape(3, 3)
    return np.array([data.cam_xpos[camera, 0], data.cam_xpos[camera, 1],
                     np.arctan2(xmat[1, 0], xmat[0, 0])])


def planar_chain(spec: MujocoSpec) -> PlanarChain:
    """The planar chain of ``spec``'s joints and camera, checked against MuJoCo's
    kinematics; a ConfigError says where the model is not one."""
    import mujoco

    model, data = spec.model, mujoco.MjData(spec.model)
    where = f"mujoco.model: {spec.path.name}: the ground truth describes a planar chain"
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    axes = data.xaxis[list(spec.joints)]
    if not np.allclose(axes, [0.0, 0.0, 1.0], atol=1e-9):
        raise ConfigError(f"{where} of hinges about +z; joints {', '.join(spec.joint_names)} "
                          f"have axes {np.round(axes, 6).tolist()}")
    anchors = data.xanchor[list(spec.joints), :2].copy()
    eye0 = camera_pose(data, spec.camera)
    links = np.diff(np.vstack([anchors, eye0[None, :2]]), axis=0)
    lengths = np.hypot(links[:, 0], links[:, 1])
    on_axis = lengths[-1] < 1e-9 * max(1.0, lengths.sum())
    if on_axis:
        links, lengths = links[:-1], lengths[:-1]
    if not len(lengths) or not np.all(lengths > 0):
        raise ConfigError(f"{where}: two commanded hinges share an axis")
    heading = float(np.arctan2(links[0, 1], links[0, 0]))
    if np.max(np.abs(wrap_angle(np.arctan2(links[:, 1], links[:, 0]) - heading))) > 1e-6:
        raise ConfigError(f"{where} whose links lie in one line at zero joint angles")
    chain = PlanarChain(Arm(tuple(lengths), "joint" if on_axis else "link"), anchors[0],
                        heading, float(eye0[2]) - heading)
    if chain.arm.n_joints != len(spec.joints):
        raise ConfigError(f"{where} with the camera on or beyond its last hinge")
    _check_chain(spec, chain, data)
    return chain


def _check_chain(spec: MujocoSpec, chain: PlanarChain, data) -> None:
    import mujoco

    rng = np.random.default_rng(0)
    states = rng.uniform(-np.pi, np.pi, (CHECK_STATES, len(spec.joints)))
    address = spec.model.jnt_qposadr[list(spec.joints)]
    poses = np.empty((len(states), 3))
    for row, state in enumerate(states):
        data.qpos[address] = state
        mujoco.mj_kinematics(spec.model, data)
        mujoco.mj_camlight(spec.model, data)
        poses[row] = camera_pose(data, spec.camera)
    ours, theirs = chain.arm.forward(states), chain.to_chain(poses)
    position = np.max(np.abs(ours[:, :2] - theirs[:, :2])) / chain.arm.reach
    heading = np.max(np.abs(wrap_angle(ours[:, 2] - theirs[:, 2])))
    if position > CHECK_TOLERANCE or heading > CHECK_TOLERANCE:
        raise ConfigError(f"mujoco.model: {spec.path.name}: MuJoCo's camera poses differ from the "
                          f"planar chain of links {list(chain.arm.segments)} (eye "
                          f"{chain.arm.eye!r}) by {position:.2e} of its reach and {heading:.2e} "
                          "rad: the camera must move in a plane, turned by the commanded hinges "
                          "about +z only")
