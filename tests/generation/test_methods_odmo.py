"""ODMO's capabilities: modes per action, mode sampling, interpolation, trajectory customisation."""

import numpy as np
import pytest
import torch
from django.core.management import CommandError, call_command

from motion.datasets import get_dataset
from motion.formats import npz
from generation.methods import MethodError, get_method
from generation.methods.odmo_modes import choose_components, discover_modes, fit_gmm, silhouette
from tests.generation.test_methods import planar_motions

torch.set_num_threads(1)

ACTIONS = ["walk", "wave", "jump"]
FRAMES = 12


def build(name, actions=ACTIONS, skeleton="h36m17", fps=25.0, frames=FRAMES, **config):
    cls = get_method(name)
    return cls(cls.Config(**{**cls.Config.PRESETS["tiny"], **config}), skeleton, actions, fps, frames)


@pytest.fixture(scope="module")
def clips():
    return get_dataset("demo").clips(frames=FRAMES, max_per_take=1, actions=ACTIONS)


@pytest.fixture(scope="module")
def odmo(clips):
    model = build("odmo")
    model.fit(clips, iters=30, seed=0, progress=False)
    return model


def joints_of(motions):
    return np.stack([m.joints for m in motions])


def two_clusters(seed=0):
    rng = np.random.default_rng(seed)
    points = np.concatenate([rng.normal(0.0, 0.3, (60, 2)), rng.normal(4.0, 0.3, (40, 2))])
    return points, np.repeat([0, 1], [60, 40])


def test_gmm_em_finds_two_clusters():
    points, truth = two_clusters()
    mixture, labels = fit_gmm(points, 2, np.random.default_rng(1))
    order = np.argsort(mixture["means"][:, 0])
    assert np.allclose(mixture["weights"][order], [0.6, 0.4], atol=1e-6)
    assert np.allclose(mixture["means"][order], [[0, 0], [4, 4]], atol=0.15)
    assert np.allclose(mixture["covariances"][order], 0.09 * np.eye(2), atol=0.05)
    assert (labels == labels[0]).sum() == 60 and len(set(labels[truth == 1])) == 1


def test_silhouette_matches_its_definition():
    points, truth = two_clusters()
    assert silhouette(points, truth) > 0.85
    assert abs(silhouette(points, np.random.default_rng(0).integers(2, size=100))) < 0.1
    small, labels = points[::10], truth[::10]
    distance = np.linalg.norm(small[:, None] - small[None], axis=-1)
    scores = []
    for i, label in enumerate(labels):
        same = (labels == label) & (np.arange(len(labels)) != i)
        a = distance[i, same].mean()
        b = distance[i, labels != label].mean()
        scores.append((b - a) / max(a, b))
    assert silhouette(small, labels) == pytest.approx(np.mean(scores))
    assert silhouette(points, np.zeros(100)) == 0.0


def test_number_of_modes_follows_the_papers_rule():
    assert choose_components({3: 0.5, 4: 0.6, 5: 0.61}) == 4  # S_4 > 0.95 S_5 first
    assert choose_components({3: 0.6, 4: 0.61}) == 3
    assert choose_components({3: 0.1, 4: 0.2, 5: 0.3}) == 5  # never: the largest
    rng = np.random.default_rng(0)
    five = np.concatenate([rng.normal(3 * c, 0.2, (30, 4)) for c in range(5)])
    modes = discover_modes(five, rng, min_size=10)
    assert modes["k"] == 5 and list(modes["sizes"]) == [30] * 5
    assert np.isclose(modes["weights"].sum(), 1.0)
    # Few codes: one Gaussian; components below min_size dropped but one always kept.
    assert list(discover_modes(five[:3], rng)["sizes"]) == [3]
    assert len(discover_modes(five[::15], rng, min_size=100)["sizes"]) == 1


def test_modes_are_listed_per_action(odmo, clips):
    modes = odmo.modes()
    assert list(modes) == ACTIONS
    for action, found in modes.items():
        assert len(found) >= 1 and [m["mode"] for m in found] == list(range(len(found)))
        sizes = [m["size"] for m in found]
        assert sizes == sorted(sizes, reverse=True)
        assert sum(sizes) <= sum(c.action == action for c in clips)
        assert sum(m["weight"] for m in found) == pytest.approx(1.0)


def test_sampling_a_mode_is_deterministic_and_modes_differ(odmo):
    action = next(a for a, found in odmo.modes().items() if len(found) >= 2)
    first = joints_of(odmo.sample([action] * 3, seed=4, mode=0))
    assert np.array_equal(first, joints_of(odmo.sample([action] * 3, seed=4, mode=0)))
    assert not np.allclose(first, joints_of(odmo.sample([action] * 3, seed=4, mode=1)))
    codes = odmo.latent_codes([action] * 50, seed=4, mode=1)
    means = odmo.extras["modes"][action]["means"]
    assert np.linalg.norm(codes.mean(0) - means[1]) < np.linalg.norm(codes.mean(0) - means[0])
    with pytest.raises(MethodError, match="has .* mode"):
        odmo.sample([action], mode=99)


def test_interpolation_runs_between_mode_draws(odmo):
    action = next(a for a, found in odmo.modes().items() if len(found) >= 2)
    steps = 5
    codes = odmo.latent_codes([action] * steps, seed=2, interpolate=(0, 1))
    start = odmo.latent_codes([action], seed=2, mode=0)[0]
    end = odmo.latent_codes([action], seed=2, mode=1)[0]
    assert np.allclose(codes[0], start) and np.allclose(codes[-1], end)
    assert np.allclose(codes, start + np.linspace(0, 1, steps)[:, None] * (end - start))
    motions = joints_of(odmo.sample([action] * steps, seed=2, interpolate=(0, 1)))
    assert np.allclose(motions[0], odmo.sample([action], seed=2, mode=0)[0].joints, atol=1e-5)
    assert np.allclose(motions[-1], odmo.sample([action], seed=2, mode=1)[0].joints, atol=1e-5)


def test_trajectory_customisation_reaches_the_end(odmo):
    wanted = ["walk", "wave", "jump"] * 2
    target = [1.0, -0.5]  # horizontal x, y of h36m17 (z up), metres from the start
    free = odmo.end_distance(odmo.sample(wanted, seed=1), target)
    steered = odmo.sample(wanted, seed=1, end=target)
    assert odmo.end_distance(steered, target).mean() < 0.1 * free.mean()
    assert odmo.end_distance(steered, target).max() < 0.05
    rows = np.array([[0.5, 0.0, 0.0], [-0.5, 0.3, 0.1]] * 3)
    assert odmo.end_distance(odmo.sample(wanted, seed=1, end=rows), rows).max() < 0.05
    with pytest.raises(MethodError, match="end must give 3 coordinates"):
        odmo.sample(["walk"], end=[1.0])


def test_odmo_conv_has_one_gaussian_per_action(clips):
    model = build("odmo_conv")
    model.fit(clips, iters=2, seed=0, progress=False)
    sizes = {a: [m["size"] for m in found] for a, found in model.modes().items()}
    assert sizes == {a: [24] for a in ACTIONS}
    assert model.sample(["walk"] * 2, seed=0, mode=0)[0].frames == FRAMES
    with pytest.raises(MethodError, match="1 mode"):
        model.sample(["walk"], mode=1)


def test_odmo_works_on_2d_skeletons():
    motions = planar_motions(count=8)
    model = build("odmo", actions=ACTIONS[:2], skeleton="h36m15_2d", fps=16.7, frames=10)
    model.fit(motions, iters=30, seed=0, progress=False)
    target = [-60.0, -20.0]  # pixels from the start, in the image plane
    steered = joints_of(model.sample(["walk", "wave"] * 2, seed=0, end=target))
    assert steered.shape == (4, 10, 15, 2) and np.isfinite(steered).all()
    free = joints_of(model.sample(["walk", "wave"] * 2, seed=0))
    assert model.end_distance(steered, target).mean() < 0.25 * model.end_distance(free, target).mean()
    with pytest.raises(MethodError, match="end must give 2 coordinates"):
        model.sample(["walk"], end=[1.0, 2.0, 3.0])


def test_sample_command_lists_and_uses_modes(tmp_path, capsys):
    checkpoint = tmp_path / "odmo.pt"
    call_command("train", "odmo", "--dataset", "demo", "--actions", "walk,wave", "--preset", "tiny",
                 "--frames", "10", "--iters", "2", "--out", str(checkpoint), verbosity=0)
    capsys.readouterr()
    call_command("sample", "odmo", "--checkpoint", str(checkpoint), "--action", "all", "--list-modes")
    listing = capsys.readouterr().out
    assert listing.startswith("walk: ") and "\nwave: " in listing and "mode 0: " in listing
    out = tmp_path / "odmo.npz"
    for flags in (["--mode", "0"], ["--end", "0.5,0.2"], ["--interpolate", "0,0"]):
        call_command("sample", "odmo", "--checkpoint", str(checkpoint), "--action", "walk",
                     "--n", "2", "--out", str(out), *flags)
        assert [m.action for m in npz.load(out)] == ["walk", "walk"]
    a2m = tmp_path / "a2m.pt"
    call_command("train", "a2m", "--dataset", "demo", "--actions", "walk", "--preset", "tiny",
                 "--frames", "10", "--iters", "1", "--out", str(a2m), verbosity=0)
    with pytest.raises(CommandError, match="has no modes"):
        call_command("sample", "a2m", "--checkpoint", str(a2m), "--action", "walk", "--list-modes")
    with pytest.raises(CommandError, match="--out"):
        call_command("sample", "odmo", "--checkpoint", str(checkpoint), "--action", "walk")


def test_paper_preset_has_neither_addition_and_demo_has_both():
    cls = get_method("odmo")
    paper, demo = cls.Config.preset("paper"), cls.Config.preset("demo")
    assert (paper.exact_end, paper.pose_about_path) == (False, False)
    assert (demo.exact_end, demo.pose_about_path) == (True, True)
    with pytest.raises(ValueError, match="exact_end must be true or false"):
        cls.Config(exact_end="yes")


@pytest.mark.parametrize("exact_end", [False, True])
@pytest.mark.parametrize("pose_about_path", [False, True])
def test_end_and_path_options(clips, exact_end, pose_about_path):
    """Only with exact_end does the guide path end at r_e whatever the training."""
    model = build("odmo", exact_end=exact_end, pose_about_path=pose_about_path)
    model.fit(clips, iters=2, seed=0, progress=False)
    labels = torch.tensor([0, 1, 2])
    condition = model.condition(labels, torch.randn(3, model.config.latent))
    end = torch.tensor([[0.7, -0.4, 0.1]] * 3)
    motion = model.networks["motion"]
    with torch.no_grad():
        path = model.networks["trajectory"](condition, end, FRAMES).cumsum(dim=1)
        poses = motion(path, condition)
        motion.about_path = not pose_about_path  # the same weights, the other choice
        other = motion(path, condition)
        motion.about_path = pose_about_path
    assert torch.allclose(path[:, -1], end, atol=1e-5) == exact_end
    # pose_about_path adds r̂_t to every joint of the first decoded pose (later poses differ
    # through the fed-back previous pose too).
    about, plain = (poses, other) if pose_about_path else (other, poses)
    assert torch.allclose(about[:, 0] - plain[:, 0], path[:, 0].repeat(1, about.shape[-1] // 3), atol=1e-5)
    steered = model.sample(["walk", "wave"], seed=1, end=[0.7, -0.4])
    assert np.isfinite(joints_of(steered)).all()


def test_checkpoints_before_the_options_load_with_both_on(odmo, tmp_path):
    checkpoint = odmo.to_checkpoint()
    del checkpoint["method_version"]
    for key in ("exact_end", "pose_about_path"):
        del checkpoint["config"][key]
    torch.save(checkpoint, tmp_path / "old.pt")
    old = get_method("odmo").load(tmp_path / "old.pt")
    assert old.config.exact_end and old.config.pose_about_path
    assert np.array_equal(joints_of(old.sample(["walk"], seed=3)), joints_of(odmo.sample(["walk"], seed=3)))


def test_real_clips_get_the_mode_of_their_code(odmo, clips):
    modes = odmo.clip_modes(clips)
    counts = {a: len(found) for a, found in odmo.modes().items()}
    assert modes.shape == (len(clips),) and modes.dtype.kind == "i"
    assert all(0 <= k < counts[clip.action] for k, clip in zip(modes, clips))
    short = get_dataset("demo").clips(frames=FRAMES - 2, max_per_take=1, actions=["walk"])[:1]
    with pytest.raises(MethodError, match="real clip to find the mode of 0 .* fewer than the model's 12"):
        odmo.clip_modes(short)
