"""Lie algebra maps and forward/inverse kinematics of generation.methods.kinematics."""

import math

import numpy as np
import pytest
import torch

from generation.methods.kinematics import (
    Kinematics,
    clip_bone_lengths,
    rest_directions,
    rotation_between,
    so3_exp,
    so3_log,
)
from motion.skeletons import get_skeleton

torch.set_num_threads(1)


def random_so3(count, seed, max_angle=math.pi - 1e-3):
    generator = torch.Generator().manual_seed(seed)
    axis = torch.randn(count, 3, generator=generator, dtype=torch.float64)
    axis = axis / axis.norm(dim=-1, keepdim=True)
    angle = torch.rand(count, 1, generator=generator, dtype=torch.float64) * max_angle
    return axis * angle


def random_joints(skeleton, shape, seed):
    rng = np.random.default_rng(seed)
    return torch.from_numpy(rng.normal(size=shape + (skeleton.n_joints, skeleton.dims)))


def test_exp_gives_rotations():
    rot = so3_exp(random_so3(200, seed=0))
    eye = torch.eye(3, dtype=torch.float64)
    assert torch.allclose(rot @ rot.transpose(-1, -2), eye.expand_as(rot), atol=1e-12)
    assert torch.allclose(torch.linalg.det(rot), torch.ones(200, dtype=torch.float64))


@pytest.mark.parametrize("scale", [1.0, 1e-6, 0.0])
def test_log_inverts_exp(scale):
    w = random_so3(500, seed=1) * scale
    assert torch.allclose(so3_log(so3_exp(w)), w, atol=1e-9)


def test_log_near_pi_gives_the_same_rotation():
    w = random_so3(50, seed=2)
    w = w / w.norm(dim=-1, keepdim=True) * (math.pi - 1e-7)
    rot = so3_exp(w)
    back = so3_log(rot)
    assert torch.allclose(so3_exp(back), rot, atol=1e-6)
    assert torch.all(back.norm(dim=-1) <= math.pi + 1e-9)


def test_exp_gradient_is_finite_at_zero():
    w = torch.zeros(4, 3, requires_grad=True)
    so3_exp(w).sum().backward()
    assert torch.isfinite(w.grad).all()


def test_rotation_between_takes_u_to_v_even_when_opposite():
    generator = torch.Generator().manual_seed(3)
    u = torch.randn(20, 3, generator=generator, dtype=torch.float64)
    u = u / u.norm(dim=-1, keepdim=True)
    v = torch.cat([-u[:5], torch.randn(15, 3, generator=generator, dtype=torch.float64)])
    v = v / v.norm(dim=-1, keepdim=True)
    rot = rotation_between(u, v)
    assert torch.allclose((rot @ u[..., None])[..., 0], v, atol=1e-12)
    assert torch.allclose(torch.linalg.det(rot), torch.ones(20, dtype=torch.float64))


@pytest.mark.parametrize("name", ["h36m17", "humanact12"])
@pytest.mark.parametrize("frames", ["chain", "tree"])
def test_inverse_then_forward_reproduces_3d_joints(name, frames):
    skeleton = get_skeleton(name)
    joints = random_joints(skeleton, (6, 5), seed=4)
    kin = Kinematics(skeleton, rest_directions(skeleton, joints.numpy()), frames)
    lengths = torch.from_numpy(skeleton.bone_lengths(joints.numpy()))
    params, root = kin.inverse(joints)
    assert params.shape == (6, 5, skeleton.n_joints - 1, 3)
    assert torch.allclose(kin.forward(params, root, lengths), joints, atol=1e-5)


@pytest.mark.parametrize("frames", ["chain", "tree"])
def test_forward_keeps_bone_lengths_and_round_trips(frames):
    skeleton = get_skeleton("humanact12")
    rest = rest_directions(skeleton, random_joints(skeleton, (50,), seed=5).numpy())
    kin = Kinematics(skeleton, rest, frames)
    params = random_so3(40 * kin.n_bones, seed=6).reshape(40, kin.n_bones, 3)
    lengths = torch.from_numpy(np.random.default_rng(7).uniform(0.05, 0.5, skeleton.n_joints))
    joints = kin.forward(params, torch.zeros(40, 3, dtype=torch.float64), lengths)
    measured = skeleton.bone_lengths(joints.numpy())
    expected = lengths.numpy().copy()
    expected[skeleton.root] = 0.0
    assert np.allclose(measured, expected, atol=1e-12)
    again = kin.forward(*kin.inverse(joints), lengths)
    assert torch.allclose(again, joints, atol=1e-5)


def test_inverse_then_forward_reproduces_2d_joints_with_foreshortening():
    skeleton = get_skeleton("h36m15_2d")
    joints = random_joints(skeleton, (4, 9), seed=8) * 100.0
    lengths = torch.from_numpy(clip_bone_lengths(skeleton, joints.numpy()))  # (4, J): per clip
    kin = Kinematics(skeleton, rest_directions(skeleton, joints.numpy()))
    params, root = kin.inverse(joints, lengths[:, None])
    assert params.shape == (4, 9, skeleton.n_joints - 1, 2)
    assert torch.allclose(kin.forward(params, root, lengths[:, None]), joints, atol=1e-5)


def test_2d_inverse_needs_bone_lengths():
    skeleton = get_skeleton("h36m15_2d")
    joints = random_joints(skeleton, (3,), seed=9)
    kin = Kinematics(skeleton, rest_directions(skeleton, joints.numpy()))
    with pytest.raises(ValueError, match="bone lengths"):
        kin.inverse(joints)


def test_bones_rest_where_few_poses_point_the_other_way():
    skeleton = get_skeleton("h36m17")
    rng = np.random.default_rng(10)
    joints = np.zeros((100, skeleton.n_joints, 3))
    heading = rng.uniform(0, 2 * np.pi, 100)
    # The right hip points sideways in every direction of the floor; the right knee straight down.
    joints[:, 1] = np.stack([np.cos(heading), np.sin(heading), np.zeros(100)], -1) * 0.1
    joints[:, 2] = joints[:, 1] + [0, 0, -0.4]
    rest = rest_directions(skeleton, joints)
    assert np.allclose(rest[1], [0, 0, 1])
    assert np.allclose(rest[2], [0, 0, -1])
    assert np.allclose(rest[0], 0)


def test_rest_directions_of_the_wrong_shape_are_refused():
    with pytest.raises(ValueError, match="rest directions must have shape"):
        Kinematics("h36m17", np.zeros((5, 3)))
