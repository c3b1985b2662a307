"""Bodies the paper strategy's tests run on: the catalogue's arms
(config/bodies/*.yaml, the sensor codes left out: the strategy uses the
forward model) and eyes fixed to their last link, which no catalogue body
has. Each with motor states whose tip lies in its working region."""
from pathlib import Path

import numpy as np
import yaml

from sensorispace_ros.core.arm import Arm

CATALOGUE = Path(__file__).resolve().parents[2] / "config" / "bodies"
CATALOGUE_BODIES = ("paper", "five-joint", "three-joint", "level-eye", "degrees")


def catalogue_arm(name: str) -> Arm:
    document = yaml.safe_load((CATALOGUE / f"{name}.yaml").read_text())
    return Arm.from_config(document["/**"]["ros__parameters"]["arm"])


def catalogue_m0(name: str) -> np.ndarray:
    document = yaml.safe_load((CATALOGUE / f"{name}.yaml").read_text())
    return np.asarray(document["/**"]["ros__parameters"]["arm"]["initial_motor_state"], float)


BODIES = {name: catalogue_arm(name) for name in CATALOGUE_BODIES}
BODIES["link-eye-1d"] = Arm((1.0, 0.8, 0.9, 0.5), "link", "rad")       # 3 free links: 1-D
BODIES["link-eye-0d"] = Arm((1.2, 1.0, 0.6), "link", "rad")            # 2 free links: 0-D
BODIES["uneven-1d"] = Arm((1.3, 0.6, 0.9), "joint", "deg")             # Grashof and not
BODIES["level-2d"] = Arm((0.9, 0.7, 0.8, 0.6), "level", "rad")          # 4 free links: 2-D


def random_states(body_arm: Arm, count: int, seed: int = 0) -> np.ndarray:
    """``count`` motor states (in the arm's unit) away from stretched and
    folded configurations: every relative link angle at least 0.2 rad
    from 0 and pi, tip more than 0.05 inside the reach."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        angles = rng.uniform(-np.pi, np.pi, body_arm.n_joints)
        bends = np.abs(np.sin(angles[1:body_arm.n_links]))
        pose = body_arm.forward(body_arm.from_radians(angles))
        if np.all(bends > np.sin(0.2)) and np.hypot(*pose[:2]) < body_arm.reach - 0.05:
            out.append(body_arm.from_radians(angles))
    return np.asarray(out)
