"""The method registry: one contract test over every method, then per-method capabilities."""

import numpy as np
import pytest
import torch
from django.core.management import CommandError, call_command

from motion.datasets import get_dataset
from motion.formats import npz
from generation.methods import (
    CheckpointError,
    MethodError,
    get_method,
    list_methods,
    load_checkpoint,
)
from generation.methods.kinematics import Kinematics
from motion.motion import Motion
from motion.skeletons import get_skeleton

torch.set_num_threads(1)

ACTIONS = ["walk", "wave", "jump"]
FRAMES = 12


@pytest.fixture(scope="module")
def clips():
    """Return short real-like clips (the synthetic demo data: constant bone lengths)."""
    return get_dataset("demo").clips(frames=FRAMES, max_per_take=1, actions=ACTIONS)


def planar_motions(count=6, frames=10, seed=0):
    """Return 2D motions made by forward kinematics of smooth random angles and tilts."""
    skeleton = get_skeleton("h36m15_2d")
    rest = np.zeros((skeleton.n_joints, 2))
    rest[:, 1] = -1.0  # every bone starts pointing up the image
    rest[skeleton.root] = 0.0
    kin = Kinematics(skeleton, rest)
    rng = np.random.default_rng(seed)
    time = np.linspace(0, 1, frames)[:, None, None]
    motions = []
    for i in range(count):
        phase = rng.uniform(0, 2 * np.pi, (1, kin.n_bones, 2))
        params = rng.uniform(-1, 1, (1, kin.n_bones, 2)) + 0.3 * np.sin(2 * np.pi * time + phase)
        root = np.stack([500 + 40 * time[:, 0, 0], np.full(frames, 400.0)], -1)
        lengths = rng.uniform(30, 60, skeleton.n_joints)
        joints = kin.forward(torch.from_numpy(params), torch.from_numpy(root), lengths)
        motions.append(Motion(joints.numpy(), skeleton.name, 16.7, ACTIONS[i % 2]))
    return motions


def build(name, clips, **config):
    cls = get_method(name)
    cfg = cls.Config(**{**cls.Config.PRESETS["tiny"], **config})
    first = clips[0]
    actions = sorted({c.action for c in clips}, key=ACTIONS.index)
    return cls(cfg, first.skeleton, actions, first.fps, FRAMES if first.frames >= FRAMES else first.frames)


_TRAINED = {}


@pytest.fixture
def trained(request, clips, tmp_path_factory):
    """Return (model, checkpoint path) of a method trained for a few iterations, once per method."""
    name = request.param
    if name not in _TRAINED:
        model = build(name, clips)
        model.fit(clips, iters=3, seed=0, progress=False)
        path = model.save(tmp_path_factory.mktemp(name) / f"{name}.pt")
        _TRAINED[name] = (model, path)
    return _TRAINED[name]


def joints_of(motions):
    return np.stack([m.joints for m in motions])


def test_registry_lists_the_methods():
    assert {"a2m", "cond_gru"} <= set(list_methods())
    with pytest.raises(KeyError, match="a2m"):
        get_method("no_such_method")


@pytest.mark.parametrize("name", list_methods())
def test_presets_build(name):
    cls = get_method(name)
    assert cls.Config.preset("paper") == cls.Config()
    with pytest.raises(ValueError, match="tiny"):
        cls.Config.preset("huge")


@pytest.mark.parametrize("trained", list_methods(), indirect=True)
def test_contract_samples(trained):
    model, _ = trained
    wanted = ["walk", "wave", "walk", "jump"]
    motions = model.sample(wanted, seed=0)
    skeleton = get_skeleton(model.skeleton)
    assert joints_of(motions).shape == (4, FRAMES, skeleton.n_joints, skeleton.dims)
    assert [m.action for m in motions] == wanted
    assert all(m.source == model.name and m.fps == model.fps for m in motions)
    assert np.isfinite(joints_of(motions)).all()
    assert model.sample(wanted, frames=5, seed=0)[0].frames == 5


@pytest.mark.parametrize("trained", list_methods(), indirect=True)
def test_contract_determinism_per_seed(trained):
    model, _ = trained
    wanted = ACTIONS * 2
    same = joints_of(model.sample(wanted, seed=7))
    assert np.array_equal(same, joints_of(model.sample(wanted, seed=7)))
    assert not np.array_equal(same, joints_of(model.sample(wanted, seed=8)))


@pytest.mark.parametrize("trained", list_methods(), indirect=True)
def test_contract_checkpoint_round_trip(trained):
    model, path = trained
    loaded = load_checkpoint(path)
    assert type(loaded) is type(model)
    assert (loaded.config, loaded.actions, loaded.iteration) == (model.config, model.actions, 3)
    assert np.array_equal(joints_of(loaded.sample(ACTIONS, seed=3)),
                          joints_of(model.sample(ACTIONS, seed=3)))


@pytest.mark.parametrize("name", list_methods())
def test_contract_training_is_seeded_and_resumable(name, clips, tmp_path):
    whole = build(name, clips)
    whole.fit(clips, iters=4, seed=5, progress=False)
    again = build(name, clips)
    again.fit(clips, iters=2, seed=5, progress=False)
    path = again.save(tmp_path / "half.pt")
    resumed = get_method(name).load(path)
    resumed.fit(clips, iters=2, seed=5, progress=False)
    assert resumed.iteration == 4
    for key, net in whole.networks.items():
        for (param, a), b in zip(net.state_dict().items(), resumed.networks[key].state_dict().values()):
            assert torch.equal(a, b), f"{key}.{param} differs after resuming"


@pytest.mark.parametrize("trained", list_methods(), indirect=True)
def test_contract_unknown_action_lists_the_known_ones(trained):
    model, _ = trained
    with pytest.raises(MethodError, match="its actions are walk, wave, jump"):
        model.sample(["walk", "moonwalk"])
    with pytest.raises(MethodError, match=r"\['walk'\]"):
        model.sample("walk")


@pytest.mark.parametrize("trained", list_methods(), indirect=True)
def test_contract_checkpoint_errors(trained, tmp_path):
    model, path = trained
    other = next(name for name in list_methods() if name != model.name)
    with pytest.raises(CheckpointError, match=f"holds a checkpoint of '{model.name}', not of '{other}'"):
        get_method(other).load(path)
    with pytest.raises(CheckpointError, match="trained on skeleton 'h36m17', not 'humanact12'"):
        get_method(model.name).load(path, skeleton="humanact12")
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(path.read_bytes()[:500])
    with pytest.raises(CheckpointError, match="not a readable checkpoint"):
        load_checkpoint(truncated)
    with pytest.raises(CheckpointError, match="does not exist"):
        load_checkpoint(tmp_path / "missing.pt")


@pytest.mark.parametrize("name", list_methods())
def test_contract_refuses_unfit_clips(name, clips):
    model = build(name, clips)
    with pytest.raises(MethodError, match="fewer than the model's"):
        model.fit([c.with_joints(c.joints[:4]) for c in clips[:2]], iters=1, progress=False)
    with pytest.raises(MethodError, match="has not been trained"):
        model.sample(["walk"])


@pytest.mark.parametrize("trained", ["a2m"], indirect=True)
def test_a2m_bone_lengths_are_exactly_the_data_medians(trained):
    model, _ = trained
    skeleton = get_skeleton(model.skeleton)
    lengths = skeleton.bone_lengths(joints_of(model.sample(ACTIONS * 2, seed=0)))
    assert lengths.std(axis=1).max() < 1e-5
    assert np.allclose(lengths, model.extras["bone_lengths"], atol=1e-5)


def test_a2m_draws_the_same_motion_with_another_skeleton(clips):
    model = build("a2m", clips)
    model.fit(clips, iters=2, seed=0, progress=False)
    skeleton = get_skeleton(model.skeleton)
    other = skeleton.bone_lengths(clips[-1].joints[0]) * 1.3
    default = joints_of(model.sample(ACTIONS, seed=4))
    swapped = joints_of(model.sample(ACTIONS, seed=4, bone_lengths=other))
    measured = skeleton.bone_lengths(swapped)
    assert np.allclose(measured, np.broadcast_to(other, measured.shape), atol=1e-4)

    def directions(joints):
        vectors = joints - joints[..., [max(p, 0) for p in skeleton.parents], :]
        return np.delete(vectors / np.linalg.norm(vectors, axis=-1, keepdims=True).clip(1e-9), skeleton.root, -2)

    assert np.allclose(directions(default), directions(swapped), atol=1e-4)
    assert np.allclose(default[:, :, skeleton.root], swapped[:, :, skeleton.root], atol=1e-5)
    with pytest.raises(MethodError, match=r"bone_lengths must have shape \(17,\)"):
        model.sample(["walk"], bone_lengths=[0.3] * 5)


def test_a2m_has_the_papers_size():
    model = get_method("a2m")(None, "humanact12", [f"class{i}" for i in range(12)], 20.0, 60)
    sizes = {k: sum(p.numel() for p in net.parameters()) for k, net in model.networks.items()}
    assert sizes == {"posterior": 117_820, "prior": 117_820, "generator": 227_110}  # Table 3


def test_a2m_works_on_2d_skeletons():
    motions = planar_motions()
    cls = get_method("a2m")
    model = cls(cls.Config.preset("tiny"), "h36m15_2d", ACTIONS[:2], 16.7, 10)
    model.fit(motions, iters=2, seed=0, progress=False)
    joints = joints_of(model.sample(["walk", "wave"], seed=0))
    assert joints.shape == (2, 10, 15, 2) and np.isfinite(joints).all()
    # Planar bones foreshorten by cos(tilt) but never exceed their full length.
    lengths = get_skeleton("h36m15_2d").bone_lengths(joints)
    assert (lengths <= model.extras["bone_lengths"] + 1e-3).all()


def test_cond_gru_starts_from_a_real_first_pose(clips):
    model = build("cond_gru", clips)
    model.fit(clips, iters=2, seed=0, progress=False)
    firsts = {action: np.stack([c.joints[0] for c in clips if c.action == action]) for action in ACTIONS}
    for motion in model.sample(ACTIONS * 2, seed=11):
        distance = np.abs(firsts[motion.action] - motion.joints[0]).max(axis=(1, 2))
        assert distance.min() == 0.0


def test_cond_gru_needs_training_clips_of_the_action(clips):
    walks = [c for c in clips if c.action == "walk"]
    cls = get_method("cond_gru")
    model = cls(cls.Config.preset("tiny"), "h36m17", ["walk", "wave"], walks[0].fps, FRAMES)
    model.fit(walks, iters=1, progress=False)
    with pytest.raises(MethodError, match="no first pose of action 'wave'"):
        model.sample(["wave"])


def test_train_and_sample_commands(tmp_path, capsys):
    checkpoint = tmp_path / "a2m.pt"
    common = ["--dataset", "demo", "--actions", "walk,wave", "--preset", "tiny",
              "--frames", "10", "--out", str(checkpoint)]
    call_command("train", "a2m", "--iters", "2", *common, verbosity=0)
    assert load_checkpoint(checkpoint).iteration == 2
    call_command("train", "a2m", "--iters", "3", "--resume", *common, verbosity=0)
    assert str(checkpoint) in capsys.readouterr().out
    assert load_checkpoint(checkpoint).iteration == 3

    out = tmp_path / "a2m.npz"
    call_command("sample", "a2m", "--checkpoint", str(checkpoint), "--action", "walk",
                 "--action", "wave", "--n", "2", "--out", str(out))
    motions = npz.load(out)
    assert [m.action for m in motions] == ["walk", "walk", "wave", "wave"]
    assert {m.source for m in motions} == {"a2m"} and motions[0].frames == 10

    real = tmp_path / "real.npz"
    call_command("sample", "real", "--dataset", "demo", "--action", "all", "--n", "1",
                 "--frames", "10", "--seed", "1", "--out", str(real))
    motions = npz.load(real)
    assert len(motions) == len(get_dataset("demo").actions())
    assert {m.source for m in motions} == {"real"} and motions[0].frames == 10


def test_commands_name_what_is_valid(tmp_path):
    with pytest.raises(CommandError, match="choose 'real' or one of: .*a2m"):
        call_command("sample", "nonsense", "--action", "walk", "--out", str(tmp_path / "x.npz"))
    with pytest.raises(CommandError, match="unknown method 'nonsense'"):
        call_command("train", "nonsense", "--dataset", "demo", "--out", str(tmp_path / "x.pt"))
    with pytest.raises(CommandError, match="no action 'moonwalk'; choose from walk"):
        call_command("sample", "real", "--dataset", "demo", "--action", "moonwalk",
                     "--out", str(tmp_path / "x.npz"))
    with pytest.raises(CommandError, match="does not exist"):
        call_command("sample", "a2m", "--checkpoint", str(tmp_path / "none.pt"),
                     "--action", "walk", "--out", str(tmp_path / "x.npz"))


def test_train_sets_config_fields_of_the_preset(tmp_path):
    """sa_gcn's departures are options: --set turns one on over the paper preset and the
    checkpoint keeps it; a wrong field or value names the fix."""
    out = tmp_path / "sa_gcn.pt"
    common = ["--dataset", "demo", "--actions", "walk,wave", "--preset", "tiny", "--frames", "10",
              "--iters", "1", "--out", str(out)]
    call_command("train", "sa_gcn", *common, "--set", "init=default", "--set", "mismatch_weight=0",
                 "--set", "qk_norm=false", verbosity=0)
    config = load_checkpoint(out).config
    assert (config.init, config.mismatch_weight, config.qk_norm, config.self_loop) == \
        ("default", 0.0, False, True)
    with pytest.raises(CommandError, match="sa_gcn has no config field 'he_init'; its fields are"):
        call_command("train", "sa_gcn", *common, "--set", "he_init=true", verbosity=0)
    with pytest.raises(CommandError, match="qk_norm: 'yes' must be a bool"):
        call_command("train", "sa_gcn", *common, "--set", "qk_norm=yes", verbosity=0)
    with pytest.raises(CommandError, match="give FIELD=VALUE"):
        call_command("train", "sa_gcn", *common, "--set", "init", verbosity=0)
