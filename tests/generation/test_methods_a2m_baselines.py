"""The seed-000 ablation and GAN baselines: a2m_xyz, two_stage_gan, act_mocogan."""

import numpy as np
import pytest
import torch

from motion.datasets import get_dataset
from generation.methods import MethodError, get_method
from generation.methods.gan_common import gradient_penalty, random_frames
from motion.skeletons import get_skeleton
from tests.generation.test_methods import ACTIONS, FRAMES, build, joints_of, planar_motions

torch.set_num_threads(1)

BASELINES = ["a2m_xyz", "two_stage_gan", "act_mocogan"]


@pytest.fixture(scope="module")
def clips():
    return get_dataset("demo").clips(frames=FRAMES, max_per_take=1, actions=ACTIONS)


def weights(model):
    return {f"{key}.{name}": value.clone() for key, net in model.networks.items()
            for name, value in net.state_dict().items()}


@pytest.mark.parametrize("name", BASELINES)
def test_training_changes_weights_and_losses(name, clips):
    model = build(name, clips)
    model.fit(clips, iters=1, seed=0, progress=False)
    before, first = weights(model), dict(model.losses)
    model.fit(clips, iters=3, seed=0, progress=False)
    assert all(np.isfinite(v) for v in model.losses.values())
    assert model.losses != first
    after = weights(model)
    assert any(not torch.equal(before[k], after[k]) for k in before)


@pytest.mark.parametrize("name", BASELINES)
def test_samples_depend_on_the_action(name, clips):
    model = build(name, clips)
    model.fit(clips, iters=2, seed=0, progress=False)
    walks = joints_of(model.sample(["walk"] * 3, seed=4))
    waves = joints_of(model.sample(["wave"] * 3, seed=4))
    assert not np.allclose(walks, waves)
    # Same action, same seed: the motions of a batch still differ from one another.
    assert not np.allclose(walks[0], walks[1])


@pytest.mark.parametrize("name", BASELINES)
def test_works_on_2d_skeletons_and_more_classes(name):
    motions = planar_motions(count=6, frames=10)
    actions = ["walk", "wave", "jump", "sit"]  # more classes than the clips show
    cls = get_method(name)
    model = cls(cls.Config.preset("tiny"), "h36m15_2d", actions, 16.7, 10)
    model.fit(motions, iters=3, seed=0, progress=False)
    joints = joints_of(model.sample(actions, seed=0))
    assert joints.shape == (4, 10, 15, 2) and np.isfinite(joints).all()


def test_a2m_xyz_outputs_joints_directly(clips):
    model = build("a2m_xyz", clips)
    skeleton = get_skeleton(model.skeleton)
    decoder = model.networks["generator"].decoder
    assert decoder.out_features == skeleton.n_joints * skeleton.dims
    model.fit(clips, iters=3, seed=0, progress=False)
    assert set(model.losses) == {"recon", "kl"}
    joints = joints_of(model.sample(ACTIONS, frames=7, seed=0))
    assert joints.shape == (3, 7, skeleton.n_joints, 3)
    with pytest.raises(MethodError, match="does not take the sampling option"):
        model.sample(["walk"], bone_lengths=[0.3] * skeleton.n_joints)


def test_a2m_xyz_has_the_a2m_network_without_its_lie_layer():
    actions = [f"class{i}" for i in range(12)]
    xyz = get_method("a2m_xyz")(None, "humanact12", actions, 20.0, 60)
    lie = get_method("a2m")(None, "humanact12", actions, 20.0, 60)
    lie_layer = sum(p.numel() for p in lie.networks["generator"].lie_output.parameters())
    assert xyz.n_parameters == lie.n_parameters - lie_layer


def test_two_stage_gan_trains_poses_then_motions(clips):
    model = build("two_stage_gan", clips, pose_iterations=2)
    frozen = None
    for stage in (1, 1, 2, 2):
        assert model.stage == stage
        model.fit(clips, iters=1, seed=0, progress=False)
        prefix = "pose_" if stage == 1 else "motion_"
        assert all(key.startswith(prefix) for key in model.losses)
        if stage == 2:
            state = model.networks["pose_generator"].state_dict()
            frozen = frozen or {k: v.clone() for k, v in state.items()}
            assert all(torch.equal(frozen[k], v) for k, v in state.items())


def test_act_mocogan_classifies_with_both_discriminators(clips):
    model = build("act_mocogan", clips)
    classes = len(model.actions)
    assert model.networks["motion_discriminator"].head[-1].out_features == 1 + classes
    assert model.networks["pose_discriminator"].net[-1].out_features == 1 + classes
    plain = build("act_mocogan", clips, pose_categories=False)
    assert plain.networks["pose_discriminator"].net[-1].out_features == 1
    plain.fit(clips, iters=2, seed=0, progress=False)
    assert set(plain.losses) == {"pose_d", "motion_d", "generator"}


def test_gradient_penalty_is_zero_for_a_unit_slope_critic():
    class Slope(torch.nn.Module):
        def forward(self, x, condition):
            return x.flatten(1) @ torch.tensor([0.6, 0.8])

    generator = torch.Generator().manual_seed(0)
    real, fake = torch.randn(5, 2), torch.randn(5, 2)
    penalty = gradient_penalty(Slope(), real, fake, generator, None)
    assert penalty.item() == pytest.approx(0.0, abs=1e-10)
    frames = random_frames(torch.arange(24.0).reshape(2, 4, 3), generator)
    assert frames.shape == (2, 3) and frames[1, 0] >= 12
