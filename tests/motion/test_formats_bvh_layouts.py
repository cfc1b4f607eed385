"""BVH files in the layouts of the tools that write them: upright, on the floor, of the
figure's height, sides read, locators dropped; implausible figures warned about; the
writer round-trips through the reader."""

import re

import numpy as np
import pytest

from motion.formats import bvh, load_motions
from motion.motion import Motion
from motion.ops import axis_rotation
from motion.skeletons import get_skeleton
from tests.motion.bvh_layouts import HEIGHT, HIP_HEIGHT, LAYOUTS, write


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_each_layout_stands_on_the_floor_at_its_height(tmp_path, layout):
    path = write(tmp_path / f"{layout}.bvh", layout)
    motions = load_motions(path, "bvh")
    [motion] = motions
    assert not [note for note in motions.notes if note.startswith("warning")], motions.notes
    skeleton = get_skeleton(motion.skeleton)
    y = motion.joints[..., 1]
    np.testing.assert_allclose(y.max(axis=1) - y.min(axis=1), HEIGHT, atol=0.03)
    np.testing.assert_allclose(y.min(axis=1), 0.0, atol=0.03)
    assert skeleton.n_joints == skeleton.joint_names.__len__()
    assert sum(1 for p in skeleton.parents if p < 0) == 1
    assert "joint_Root" not in skeleton.joint_names, "a static root is a locator, not a bone"
    assert len(skeleton.left) == len(skeleton.right) >= 8, (skeleton.joint_names, skeleton.left)
    root = skeleton.parents.index(-1)
    np.testing.assert_allclose(motion.joints[0, root, 1], HIP_HEIGHT, atol=1e-3)
    if LAYOUTS[layout]["smpl22"]:
        [mapped] = load_motions(path, "bvh", skeleton="smpl22")
        joints = mapped.joints
        np.testing.assert_allclose(joints[:, 0, 1], HIP_HEIGHT + 0.02 * np.sin(np.arange(4)),
                                   atol=1e-3)
        feet = joints[:, [7, 8, 10, 11], 1]
        assert feet.min() > -0.02 and feet.min(axis=1).max() < 0.03
        assert 1.3 < joints[0, 15, 1] <= HEIGHT + 1e-3, "the head above the neck, at most the top"
        shins = np.linalg.norm(joints[:, 4] - joints[:, 7], axis=-1)
        np.testing.assert_allclose(shins, 0.42, atol=1e-3)  # Bandai's came out doubled


def test_the_mixamo_root_offset_is_replaced_not_added(tmp_path):
    motion = bvh.read(write(tmp_path / "m.bvh", "mixamo"))
    hips = motion.joint_names.index("mixamorig:Hips")
    np.testing.assert_allclose(motion.positions[:, hips, 2], 0.3 * np.arange(4), atol=1e-4)
    assert motion.positions[:, hips, 1].max() < 1.0


def test_implausible_figures_are_warned_about_saying_what_was_assumed(tmp_path):
    floating = load_motions(write(tmp_path / "float.bvh", "lafan1", lift=0.8), "bvh")
    [warning] = floating.notes
    assert "float.bvh" in warning and "0.80 m above the floor" in warning
    assert "assumed y up" in warning and "--up" in warning
    text = (tmp_path / "big.bvh")
    write(text, "momask_joints2bvh")
    tall = bvh.read(text, scale=2.3)
    [warning] = [w for w in tall.warnings if "tall" in w]
    assert re.search(r"3\.[78]\d m tall", warning) and "as given" in warning and "--scale" in warning


def test_sides_come_from_suffixes_and_prefixes():
    from motion.skeletons import side_of_name

    sides = {name: side_of_name(name) for name in (
        "UpperLeg_L", "Hand_R", "thigh.L", "shin.R", "l_hip", "r_knee", "LeftArm",
        "RightUpLeg", "Left_knee", "mixamorig:LeftHand", "Hips", "Chest", "joint_Root",
        "LowerLeg_L")}
    assert [n for n, s in sides.items() if s == "left"] == [
        "UpperLeg_L", "thigh.L", "l_hip", "LeftArm", "Left_knee", "mixamorig:LeftHand",
        "LowerLeg_L"]
    assert [n for n, s in sides.items() if s == "right"] == [
        "Hand_R", "shin.R", "r_knee", "RightUpLeg"]


@pytest.mark.parametrize("skeleton", ["smpl22", "h36m17"])
def test_the_writer_round_trips_through_the_reader(tmp_path, skeleton):
    rng = np.random.default_rng(3)
    [source] = load_motions(write(tmp_path / "walk.bvh", "lafan1"), "bvh", skeleton=skeleton)
    joints = source.joints + rng.normal(scale=0.01, size=source.joints.shape).astype(np.float32)
    motion = Motion(joints, skeleton, 30.0, "walk", "real", text="a person walks")
    path = bvh.save(tmp_path / "out.bvh", motion)
    [back] = load_motions(path, "bvh", skeleton=skeleton, scale="cm")
    np.testing.assert_allclose(back.joints, motion.joints, atol=1e-4)
    assert back.fps == 30.0
    [own] = load_motions(path, "bvh")  # its own skeleton: the same joints, y up, metres
    names = get_skeleton(skeleton).joint_names
    order = [get_skeleton(own.skeleton).joint_names.index(name) for name in names]
    turn = axis_rotation(get_skeleton(skeleton).up, "y")
    per_unit = get_skeleton(skeleton).metres_per_unit or 1.0
    np.testing.assert_allclose(own.joints[:, order], motion.joints @ turn.T * per_unit,
                               atol=1e-4)
