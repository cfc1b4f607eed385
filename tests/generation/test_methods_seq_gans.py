"""The baselines of seeds 003/004: SkeletonVAE, SkeletonGAN, c-SkeletonGAN and SA-GCN."""

import numpy as np
import pytest
import torch
from django.core.management import call_command

from motion.datasets import get_dataset
from motion.formats import npz
from generation.methods import MethodError, get_method
from generation.methods.base import CheckpointError
from generation.methods.sa_gcn import (
    CausalSelfAttention,
    SequenceGraph,
    skeleton_adjacency,
    temporal_neighbours,
)
from motion.skeletons import get_skeleton
from tests.conftest import make_motion

torch.set_num_threads(1)

ACTIONS = ["walk", "wave", "jump"]
FRAMES = 12
METHODS = ["skeleton_vae", "skeleton_gan", "c_skeleton_gan", "sa_gcn"]
MIXING = ["c_skeleton_gan", "sa_gcn"]


@pytest.fixture(scope="module")
def clips():
    return get_dataset("demo").clips(frames=FRAMES, max_per_take=1, actions=ACTIONS)


def build(name, skeleton="h36m17", actions=ACTIONS, fps=25.0, frames=FRAMES, **changes):
    cls = get_method(name)
    return cls(cls.Config(**{**cls.Config.PRESETS["tiny"], **changes}), skeleton, actions, fps, frames)


_TRAINED = {}


@pytest.fixture
def trained(request, clips):
    """Return a model trained past its pretraining (if any), once per method."""
    if request.param not in _TRAINED:
        model = build(request.param)
        model.fit(clips, iters=4, seed=0, progress=False)
        _TRAINED[request.param] = model
    return _TRAINED[request.param]


def joints(motions):
    return np.stack([m.joints for m in motions])


def test_sa_gcn_attention_is_causal_and_keeps_the_top_5_past_frames():
    torch.manual_seed(0)
    scores, _ = CausalSelfAttention(6)(torch.randn(3, 9, 6))
    assert torch.all(scores.triu(1) == 0) and torch.allclose(scores.sum(-1), torch.ones(3, 9))
    index, weight = temporal_neighbours(scores, 5)
    assert index.shape == (3, 9, 5)
    for b in range(3):
        for t in range(9):
            kept = sorted(index[b, t][weight[b, t] > 0].tolist())
            assert len(kept) == min(t, 5) and all(s < t for s in kept)
            best = scores[b, t, :t].argsort(descending=True)[:5]
            assert kept == sorted(best.tolist())


def test_sa_gcn_sparse_graph_equals_the_dense_sequence_graph():
    """D⁻¹ (Ã_s + I) H computed sparsely equals Eq. 6-7 (plus self-loops) with the NT x NT matrix."""
    torch.manual_seed(1)
    skeleton = get_skeleton("h36m15_2d")
    adjacency = skeleton_adjacency(skeleton)
    joints, frames, k = skeleton.n_joints, 8, 3
    scores, _ = CausalSelfAttention(4)(torch.randn(2, frames, 4))
    nodes = torch.randn(2, frames, joints, 5)
    sparse = SequenceGraph(scores, adjacency, k).aggregate(nodes)

    index, weight = temporal_neighbours(scores, k)
    for b in range(2):
        mask = torch.diag(scores[b].diagonal())
        for t in range(frames):
            mask[t].index_put_((index[b, t],), weight[b, t], accumulate=True)
        # Ã_s = S_mask ⊙ Ã: Ā on the diagonal blocks, I off the diagonal.
        dense = torch.kron(torch.diag(mask.diagonal()), adjacency) + torch.kron(
            mask - torch.diag(mask.diagonal()), torch.eye(joints)) + torch.eye(frames * joints)
        normalised = dense / dense.sum(-1, keepdim=True)
        expected = (normalised @ nodes[b].reshape(frames * joints, -1)).reshape(frames, joints, -1)
        assert torch.allclose(sparse[b], expected, atol=1e-5)


def test_sa_gcn_attention_starts_as_the_identity_and_nodes_keep_their_own_frame():
    torch.manual_seed(2)
    attention = CausalSelfAttention(6)
    frames = torch.randn(2, 7, 6) * torch.arange(1, 8)[:, None]  # growing, like c_t
    scores, nodes = attention(frames)
    assert torch.equal(nodes, frames)  # γ = 0: H_in = H + γ S V starts as H
    # A frame whose own score is 0 still keeps its joints through the self-loop.
    skeleton = get_skeleton("h36m15_2d")
    joints = skeleton.n_joints
    scores = torch.zeros(1, 4, 4)
    scores[0, :, 0] = 1.0  # every frame attends only to frame 0
    hidden = torch.randn(1, 4, joints, 3)
    out = SequenceGraph(scores, skeleton_adjacency(skeleton), 3).aggregate(hidden)
    assert torch.allclose(out[0, 3], (hidden[0, 3] + hidden[0, 0]) / 2, atol=1e-6)


def test_sa_gcn_attention_does_not_saturate_in_training(clips):
    """The collapse of the unnormalised layer: its rows put ~all weight on one frame."""
    frames = 24
    long_clips = get_dataset("demo").clips(frames=frames, max_per_take=1, actions=ACTIONS)
    model = build("sa_gcn", frames=frames)
    model.fit(long_clips, iters=120, seed=0, progress=False)  # the old layer: row max 0.999
    generator = model.networks["generator"]
    classes = torch.zeros(16, len(ACTIONS))
    classes[:, 0] = 1.0
    noise = torch.randn(16, frames, model.config.noise, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        scores, _ = generator.attention(generator.frames(classes, noise))
    late = scores[:, frames // 2:]  # rows with at least 12 frames to choose from
    assert late.max(-1).values.mean() < 0.5
    assert late[..., 0].max() < 0.5  # no row gives (nearly) all its weight to frame 0
    walks = joints(model.sample(["walk"] * 8, frames=frames, seed=3))
    # Samples of one class differ (early in training a GAN's spread is small either way;
    # the collapse shows as the saturated attention above).
    assert walks.std(axis=0).mean() > 1e-4
    assert not any(np.allclose(walks[0], other, atol=1e-5) for other in walks[1:])


def test_sa_gcn_checkpoints_of_older_versions_are_a_clear_error(clips, tmp_path):
    model = build("sa_gcn")
    model.fit(clips, iters=1, progress=False)
    checkpoint = model.to_checkpoint()
    del checkpoint["method_version"]  # saved before versions were recorded: version 1
    torch.save(checkpoint, tmp_path / "old.pt")
    with pytest.raises(CheckpointError, match="sa_gcn checkpoint of version 1.*is version 4.*"
                                              "train it again"):
        get_method("sa_gcn").load(tmp_path / "old.pt")
    checkpoint["method_version"] = 2  # the same shapes, trained under another init and loss
    torch.save(checkpoint, tmp_path / "v2.pt")
    with pytest.raises(CheckpointError, match="version 2.*is version 4"):
        get_method("sa_gcn").load(tmp_path / "v2.pt")
    assert get_method("sa_gcn").load(model.save(tmp_path / "new.pt")).iteration == 1


def test_sa_gcn_version_3_checkpoints_load_with_every_departure_on(clips, tmp_path):
    """Version 3 had LayerNorm on Q/K, the gated residual, the self-loop and He init always
    on and no switches in its config: it loads as version 4 with those switches on."""
    model = build("sa_gcn", mismatch_weight=1.0)
    model.fit(clips, iters=1, progress=False)
    checkpoint = model.to_checkpoint()
    checkpoint["method_version"] = 3
    for name in ("qk_norm", "gated_residual", "self_loop", "init", "class_weight"):
        del checkpoint["config"][name]
    torch.save(checkpoint, tmp_path / "v3.pt")
    loaded = get_method("sa_gcn").load(tmp_path / "v3.pt")
    assert loaded.config.departures() == {"qk_norm": True, "gated_residual": True,
                                          "self_loop": True, "init": "he", "mismatch_weight": 1.0}
    expected = joints(model.sample(["walk", "jump"], seed=5))
    assert np.array_equal(joints(loaded.sample(["walk", "jump"], seed=5)), expected)


def test_sa_gcn_paper_preset_is_equations_1_4_6_7_alone(clips):
    """The paper preset takes no departure: no LayerNorm or gate in the attention
    (H_in = S V), no extra self-loop (D⁻¹ Ã_s H), torch's initialisation, and the
    discriminators' Eq. 1 terms only; each departure is saved in the checkpoint's config."""
    cls = get_method("sa_gcn")
    paper = cls.Config.preset("paper")
    assert paper.departures() == {}
    assert cls.Config.preset("code").departures() == {"gated_residual": True}
    model = cls(paper, "h36m17", ACTIONS, 25.0, FRAMES)
    generator = model.networks["generator"]
    assert generator.attention.norm is None and generator.attention.gate is None
    assert model.networks["video_discriminator"].classify is None
    torch.manual_seed(3)
    frames = torch.randn(2, 6, generator.joints * generator.dims)
    scores, nodes = generator.attention(frames)
    attention = generator.attention
    expected = scores @ attention.value(frames)
    assert torch.allclose(nodes, expected, atol=1e-6)  # Eq. 4: H_in = S V
    logits = attention.query(frames) @ attention.key(frames).transpose(1, 2) / frames.shape[-1] ** 0.5
    causal = logits.masked_fill(torch.ones(6, 6, dtype=torch.bool).triu(1), float("-inf"))
    assert torch.allclose(scores, causal.softmax(-1), atol=1e-6)
    # Torch's default initialisation: biases are not zeroed as He's are.
    assert generator.linears[0].bias.abs().sum() > 0


def test_sa_gcn_graph_without_self_loops_is_equation_7():
    """Without ``self_loop`` the sparse graph equals D⁻¹ Ã_s H of Eq. 6-7 built densely."""
    torch.manual_seed(4)
    skeleton = get_skeleton("h36m15_2d")
    adjacency = skeleton_adjacency(skeleton)
    joints_, frames, k = skeleton.n_joints, 7, 3
    scores, _ = CausalSelfAttention(4, qk_norm=False, gated=False)(torch.randn(2, frames, 4))
    nodes = torch.randn(2, frames, joints_, 3)
    sparse = SequenceGraph(scores, adjacency, k, self_loop=False).aggregate(nodes)
    index, weight = temporal_neighbours(scores, k)
    for b in range(2):
        mask = torch.diag(scores[b].diagonal())
        for t in range(frames):
            mask[t].index_put_((index[b, t],), weight[b, t], accumulate=True)
        dense = torch.kron(torch.diag(mask.diagonal()), adjacency) + torch.kron(
            mask - torch.diag(mask.diagonal()), torch.eye(joints_))
        normalised = dense / dense.sum(-1, keepdim=True)
        expected = (normalised @ nodes[b].reshape(frames * joints_, -1)).reshape(frames, joints_, -1)
        assert torch.allclose(sparse[b], expected, atol=1e-5)


def test_sa_gcn_class_head_trains_with_cross_entropy(clips):
    """``class_weight`` adds the authors' class head to D_V: its cross-entropy trains it on
    real and generated clips, and the generator is pushed towards the class it was asked for."""
    plain = build("sa_gcn", class_weight=0.0)
    assert plain.networks["video_discriminator"].classify is None
    model = build("sa_gcn", class_weight=1.0)
    model.fit(clips, iters=0, seed=0, progress=False)
    head = model.networks["video_discriminator"].classify
    before = head.weight.detach().clone()
    calls = []
    original = model.networks["video_discriminator"].with_logits

    def record(poses, classes):
        calls.append(poses.requires_grad)
        return original(poses, classes)

    model.networks["video_discriminator"].with_logits = record
    model.train_step(model.encode(clips[:6]), torch.Generator().manual_seed(0))
    assert len(calls) == 3  # D_V on real and fake clips, then the generator's term
    assert not torch.equal(head.weight, before)
    with pytest.raises(ValueError, match="class_weight"):
        get_method("sa_gcn").Config(class_weight=-1.0)
    with pytest.raises(ValueError, match="init must be one of"):
        get_method("sa_gcn").Config(init="xavier")


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_sa_gcn_motions_of_one_class_differ_from_the_start(clips, seed):
    """A fresh generator's motions of one class spread at a fair share of the clips' spread.

    Under torch's default initialisation its eleven linear layers each shrank their
    input: motions of one class then differed by 0.01-0.1 % of the clips' spread (tiny
    preset; on h36m2d with the demo preset about 1 %), and the GAN never spread them.
    With He initialisation the tiny preset measured 3-10 % at 12 frames.
    """
    model = build("sa_gcn")  # the tiny preset starts at He's scale (init: he)
    model.fit(clips, iters=0, seed=seed, progress=False)  # initialise, take the statistics
    walks = joints(model.sample(["walk"] * 16, seed=3))
    real = joints(clips)
    assert walks.std(axis=0).mean() > 0.01 * real.std(axis=0).mean()


def test_sa_gcn_discriminators_see_real_clips_with_wrong_labels(clips):
    """With ``mismatch_weight`` > 0 both discriminators are also shown real clips (whole,
    or their frames) under labels other than theirs, and only then; the generator's
    terms keep the true labels."""
    for weight in (0.0, 1.0):
        model = build("sa_gcn", mismatch_weight=weight)
        model.fit(clips, iters=0, seed=0, progress=False)
        batch = model.encode(clips[:6])
        labels = torch.as_tensor(batch["label"])
        calls = {"video_discriminator": [], "frame_discriminator": []}
        for key, log in calls.items():
            net = model.networks[key]

            def record(poses, classes, original=net.forward, log=log):
                log.append((poses.detach().clone(), classes.argmax(-1)))
                return original(poses, classes)

            net.forward = record
        model.train_step(batch, torch.Generator().manual_seed(0))
        for key, log in calls.items():
            wrong = [poses for poses, seen in log if torch.all(seen != labels)]
            right = [poses for poses, seen in log if torch.equal(seen, labels)]
            assert len(wrong) + len(right) == len(log), key  # no call mixes the two
            assert len(wrong) == int(weight), key  # the mismatched term: one call, or none
            assert len(right) == 3, key  # real and fake for D, fake for the generator
            if weight:
                real = batch["pose"] if key == "video_discriminator" else right[0]
                assert torch.equal(wrong[0], real), key  # the real clips, relabelled


def test_sa_gcn_generator_layers_start_at_he_scale():
    """The three linear layers and five graph convolutions start with He's variance for the
    ReLU after them (2 / fan_in; 1 / fan_in for those without) and zero biases."""
    torch.manual_seed(0)  # the first convolution has only 2 x 16 weights to measure
    generator = build("sa_gcn", linear_width=64, gc_width=16).networks["generator"]
    relu = [generator.linears[0], generator.linears[2], *generator.convolutions]
    plain = [generator.linears[4], generator.skip_1_3, generator.skip_3_5, generator.output]
    for layers, gain in ((relu, 2.0), (plain, 1.0)):
        for layer in layers:
            assert layer.bias is None or not layer.bias.any()
            expected = (gain / layer.in_features) ** 0.5
            assert 0.7 * expected < layer.weight.std().item() < 1.3 * expected, layer


def test_sa_gcn_adjacency_follows_the_bones():
    skeleton = get_skeleton("h36m17")
    adjacency = skeleton_adjacency(skeleton)
    assert torch.equal(adjacency, adjacency.T) and torch.all(adjacency.diagonal() == 1)
    assert int(adjacency.sum()) == skeleton.n_joints + 2 * len(skeleton.bones)


@pytest.mark.parametrize("trained", MIXING, indirect=True)
def test_mixed_labels(trained):
    walk = joints(trained.sample(["walk"] * 3, seed=5))
    wave = joints(trained.sample(["wave"] * 3, seed=5))
    mixed = trained.sample(["walk"] * 3, seed=5, mix={"walk": 0.5, "wave": 0.5})
    assert [m.action for m in mixed] == ["walk+wave"] * 3
    assert mixed[0].meta["mix"] == {"walk": 0.5, "wave": 0.5}
    assert not np.allclose(joints(mixed), walk) and not np.allclose(joints(mixed), wave)
    again = trained.sample(["jump"] * 3, seed=5, mix={"walk": 2, "wave": 2})
    assert np.array_equal(joints(mixed), joints(again))  # normalised, and the label is replaced
    pure = trained.sample(["wave"] * 3, seed=5, mix={"walk": 1.0})
    assert np.array_equal(joints(pure), walk) and pure[0].action == "walk"


@pytest.mark.parametrize("trained", MIXING, indirect=True)
@pytest.mark.parametrize("mix, message", [
    ({"walk": 0.5, "moonwalk": 0.5}, "'moonwalk'.*its actions are walk, wave, jump"),
    ({"walk": -0.5, "wave": 1.5}, "weight of 'walk' must be a finite non-negative"),
    ({"walk": float("nan")}, "weight of 'walk'"),
    ({"walk": "lots"}, "weight of 'walk'"),
    ({"walk": 0, "wave": 0}, "must not all be 0"),
    ({}, "mix must map action names to weights"),
    ("walk", "mix must map action names to weights"),
])
def test_invalid_mixes_are_clear_errors(trained, mix, message):
    with pytest.raises(MethodError, match=message):
        trained.sample(["walk"], mix=mix)


@pytest.mark.parametrize("name", ["skeleton_vae", "skeleton_gan"])
def test_baselines_take_no_mix(name, clips):
    model = build(name)
    model.fit(clips, iters=1, progress=False)
    with pytest.raises(MethodError, match="does not take the sampling option"):
        model.sample(["walk"], mix={"walk": 1.0})


@pytest.mark.parametrize("name", METHODS)
def test_training_changes_the_losses(name, clips):
    model = build(name)
    model.fit(clips, iters=3, seed=0, progress=False)  # past tiny pretraining (2 iterations)
    first = model.losses
    after = model.fit(clips, iters=2, seed=0, progress=False)
    assert first.keys() == after.keys() and first != after
    assert all(np.isfinite(v) for v in after.values())


@pytest.mark.parametrize("name", ["skeleton_gan", "c_skeleton_gan"])
def test_frame_decoder_is_pretrained_then_frozen(name, clips):
    model = build(name)
    model.fit(clips, iters=0, seed=0, progress=False)

    def state():
        decoder = next(iter(model.networks.values()))  # the frame decoder comes first
        return {k: v.clone() for k, v in decoder.state_dict().items()}

    start = state()
    model.fit(clips, iters=2, seed=0, progress=False)
    pretrained = state()
    assert any(not torch.equal(start[k], pretrained[k]) for k in start)
    model.fit(clips, iters=2, seed=0, progress=False)
    assert all(torch.equal(pretrained[k], v) for k, v in state().items())


@pytest.mark.parametrize("real_label", [None, "data", "classifier"])
def test_c_skeleton_gan_discriminator_labels(clips, real_label):
    """Algorithm 1 (the default): D sees one-hot data labels on real and generated pairs."""
    changes = {} if real_label is None else {"real_label": real_label}
    model = build("c_skeleton_gan", **changes)
    assert model.config.real_label == (real_label or "data")
    model.fit(clips, iters=model.config.pretrain_iters, seed=0, progress=False)
    rows = []
    hook = model.networks["discriminator"].register_forward_hook(
        lambda module, inputs, output: rows.append(inputs[1].detach().clone()))
    losses = model.fit(clips, iters=2, seed=0, progress=False)
    hook.remove()
    assert set(losses) == {"d", "g", "omega", "ce"} and rows
    one_hot_rows = [bool(torch.all((r == 0) | (r == 1)) and torch.all(r.sum(-1) == 1)) for r in rows]
    if model.config.real_label == "data":
        assert all(one_hot_rows)
    else:  # the real pair of each D update carries softmax C(x), not one-hot rows
        assert not all(one_hot_rows)


@pytest.mark.parametrize("name", METHODS)
def test_2d_skeleton_with_ten_classes(name):
    actions = [f"class{i}" for i in range(10)]
    motions = [make_motion(frames=10, seed=i, skeleton="h36m15_2d", action=actions[i % 10],
                           fps=50 / 3) for i in range(20)]
    model = build(name, skeleton="h36m15_2d", actions=actions, fps=50 / 3, frames=10)
    model.fit(motions, iters=3, seed=0, progress=False)
    sampled = joints(model.sample(actions, frames=14, seed=0))
    assert sampled.shape == (10, 14, 15, 2) and np.isfinite(sampled).all()


def test_sample_command_mixes_actions(clips, tmp_path):
    model = build("sa_gcn")
    model.fit(clips, iters=1, progress=False)
    checkpoint = model.save(tmp_path / "sa_gcn.pt")
    out = tmp_path / "mixed.npz"
    call_command("sample", "sa_gcn", "--checkpoint", str(checkpoint), "--action", "walk",
                 "--n", "2", "--mix", "walk=0.5,jump=0.5", "--out", str(out))
    assert [m.action for m in npz.load(out)] == ["walk+jump"] * 2
