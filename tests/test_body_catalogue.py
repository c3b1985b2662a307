"""The body catalogue (config/bodies/): every file is the paper configuration
with only body keys changed, and none tunes the naive agent."""
from __future__ import annotations


import pytest

from sensorispace_ros import config
from sensorispace_ros.core.arm import Arm

from shared import REPO as ROOT
CATALOGUE = sorted((ROOT / "config" / "bodies").glob("*.yaml"))
BODY_PREFIXES = ("arm.", "world.retina.")
EXPECTED = {"paper", "five-joint", "three-joint", "level-eye", "receptors-12", "degrees",
            "code-scale-1e-3", "code-scale-1e3", "code-log", "code-power-3", "code-mix"}


def test_the_catalogue_holds_the_named_bodies():
    assert {path.stem for path in CATALOGUE} == EXPECTED


@pytest.mark.parametrize("path", CATALOGUE, ids=lambda p: p.stem)
def test_a_body_file_changes_only_body_keys(path):
    paper = config.flatten(config.load_config(ROOT / "config" / "paper.yaml"))
    body = config.flatten(config.load_config(path))
    changed = {key for key in paper if paper[key] != body[key]}
    assert all(key.startswith(BODY_PREFIXES) for key in changed), sorted(changed)
    assert (path.stem == "paper") == (not changed)


@pytest.mark.parametrize("path", CATALOGUE, ids=lambda p: p.stem)
def test_no_body_file_sets_a_naive_parameter(path):
    assert not any(key.startswith("naive.")
                   for key in config.flatten(config.read_parameter_file(path)))


@pytest.mark.parametrize("name, joints, pose_rank, pov_dim", [
    ("paper", 4, 3, 1), ("five-joint", 5, 3, 2), ("three-joint", 3, 3, 0),
    ("level-eye", 3, 2, 1), ("degrees", 4, 3, 1), ("receptors-12", 4, 3, 1)])
def test_catalogue_bodies_have_the_structure_their_files_promise(name, joints, pose_rank,
                                                                    pov_dim):
    arm_cfg = config.load_config(ROOT / "config" / "bodies" / f"{name}.yaml")["arm"]
    body_arm = Arm(tuple(arm_cfg["segments"]), arm_cfg["eye"], arm_cfg["motor_unit"])
    assert (body_arm.n_joints, body_arm.pose_rank, body_arm.pov_dim) == (joints, pose_rank,
                                                                         pov_dim)
