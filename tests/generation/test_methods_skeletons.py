"""Every method trains and samples on every skeleton the project loads, 2D and 3D."""

import numpy as np
import pytest
import torch

from generation.methods import get_method, list_methods
from generation.methods.kinematics import Kinematics
from motion.motion import Motion
from motion.skeletons import get_skeleton

torch.set_num_threads(1)

CLASSES = ["a", "b", "c"]  # more classes than a single batch may show


def kinematic_motions(skeleton_name, count=6, frames=10, seed=0):
    """Return motions with constant bone lengths: forward kinematics of smooth random angles."""
    skeleton = get_skeleton(skeleton_name)
    dims = skeleton.dims
    rest = np.zeros((skeleton.n_joints, dims))
    rest[:, skeleton.up_index] = skeleton.up_sign
    rest[skeleton.root] = 0.0
    kin = Kinematics(skeleton, rest)
    rng = np.random.default_rng(seed)
    time = np.linspace(0, 1, frames)[:, None, None]
    width = 2 if dims == 2 else 3
    scale = 40.0 if dims == 2 else 0.3  # pixels or metres
    motions = []
    for i in range(count):
        phase = rng.uniform(0, 2 * np.pi, (1, kin.n_bones, width))
        params = rng.uniform(-0.5, 0.5, (1, kin.n_bones, width)) + 0.3 * np.sin(2 * np.pi * time + phase)
        root = np.zeros((frames, dims))
        root[:, 0] = np.linspace(0, 2 * scale, frames)
        root[:, skeleton.up_index] = 3 * scale * skeleton.up_sign
        lengths = rng.uniform(0.5, 1.0, skeleton.n_joints) * scale
        joints = kin.forward(torch.from_numpy(params), torch.from_numpy(root), lengths)
        motions.append(Motion(joints.numpy(), skeleton.name, 20.0, CLASSES[i % 2]))
    return motions


@pytest.mark.parametrize("skeleton", ["humanact12", "h36m15_2d"])
@pytest.mark.parametrize("name", list_methods())
def test_method_trains_and_samples_on_skeleton(name, skeleton):
    clips = kinematic_motions(skeleton)
    cls = get_method(name)
    model = cls(cls.Config.preset("tiny"), skeleton, CLASSES, 20.0, 10)
    model.fit(clips, iters=2, seed=0, progress=False)
    # cond_gru and odmo draw from the data of an action: sample trained ones
    motions = model.sample(["a", "b", "a"], frames=8, seed=3)
    joints = np.stack([m.joints for m in motions])
    n_joints, dims = get_skeleton(skeleton).n_joints, get_skeleton(skeleton).dims
    assert joints.shape == (3, 8, n_joints, dims)
    assert np.isfinite(joints).all()
    assert [m.action for m in motions] == ["a", "b", "a"]
