"""The GRU action classifier: training, features, checkpoints, the held-out split."""

import numpy as np
import pytest
import torch

from motion.datasets import get_dataset
from motion_metrics.recognition import (
    FEATURES,
    ActionClassifier,
    ClassifierConfig,
    ClassifierError,
    Split,
    make_split,
    train_classifier,
)
from tests.conftest import make_motion

torch.set_num_threads(1)

ACTIONS = ["walk", "jump", "wave"]
FRAMES = 20


@pytest.fixture(scope="module")
def clips():
    return get_dataset("demo").clips(frames=FRAMES, actions=ACTIONS, max_per_take=1)


@pytest.fixture(scope="module")
def classifier(clips):
    model = ActionClassifier(ClassifierConfig.preset("tiny"), "h36m17", ACTIONS, 25.0, FRAMES)
    model.fit(clips, 40, seed=0, progress=False)
    return model


def test_features_are_30_d_tanh_and_predictions_are_action_indices(classifier, clips):
    features = classifier.features(clips)
    assert features.shape == (len(clips), FEATURES) == (len(clips), 30)
    assert np.all(np.abs(features) <= 1.0)
    predictions = classifier.predict(clips)
    assert predictions.shape == (len(clips),) and set(predictions) <= {0, 1, 2}
    joints = np.stack([clip.joints for clip in clips])
    assert np.allclose(classifier.features(joints), features)


def test_training_learns_the_demo_actions(classifier, clips):
    assert classifier.iteration == 40
    assert classifier.accuracy(clips) > 1 / len(ACTIONS)


def test_features_ignore_where_the_motion_starts(classifier, clips):
    moved = [clip.with_joints(clip.joints + np.array([3.0, -2.0, 0.0])) for clip in clips[:5]]
    assert np.allclose(classifier.features(moved), classifier.features(clips[:5]), atol=1e-5)


def test_checkpoint_round_trip(classifier, clips, tmp_path):
    classifier.split = Split(test_takes=("walk/None/walk_00",))
    path = classifier.save(tmp_path / "clf.pt")
    loaded = ActionClassifier.load(path)
    assert (loaded.actions, loaded.skeleton, loaded.frames, loaded.fps) == (ACTIONS, "h36m17", FRAMES, 25.0)
    assert loaded.config == classifier.config and loaded.split == classifier.split
    assert np.allclose(loaded.features(clips), classifier.features(clips))


def test_wrong_inputs_are_clear_errors(classifier, clips, tmp_path):
    with pytest.raises(ClassifierError, match="skeleton 'humanact12'"):
        classifier.features([make_motion(frames=FRAMES, skeleton="humanact12")])
    with pytest.raises(ClassifierError, match="has 12 frames; this classifier reads clips of 20"):
        classifier.features([make_motion(frames=12)])
    with pytest.raises(ClassifierError, match="knows no action 'kick'"):
        classifier.labels_of([make_motion(frames=FRAMES, action="kick")])
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ClassifierError, match="not a readable checkpoint"):
        ActionClassifier.load(tmp_path / "junk.pt")
    with pytest.raises(ClassifierError, match="does not exist"):
        ActionClassifier.load(tmp_path / "missing.pt")


def test_take_split_holds_out_a_fifth_of_each_actions_takes(clips):
    split = make_split(get_dataset("demo"), clips, seed=3)
    train, test = split.divide(clips)
    assert len(train) + len(test) == len(clips)
    train_takes = {clip.meta["take"] for clip in train}
    assert not train_takes & {clip.meta["take"] for clip in test}
    for action in ACTIONS:
        takes = {clip.meta["take"] for clip in test if clip.action == action}
        assert len(takes) == round(0.2 * 24)
    assert make_split(get_dataset("demo"), clips, seed=3) == split
    with pytest.raises(ClassifierError, match="has no subjects"):
        make_split(get_dataset("demo"), clips, test_subjects="S1")


def test_subject_split_defaults_to_the_last_subjects():
    h36m = get_dataset("h36m")
    assert make_split(h36m, []) == Split(test_subjects=("S9", "S11"))
    split = make_split(h36m, [], test_subjects="S11", subjects="S1,S5")
    assert split.test_subjects == ("S11",) and split.train_subjects == ("S1", "S5")
    with pytest.raises(ClassifierError, match="S5 are both trained on and held out"):
        make_split(h36m, [], test_subjects="S5", subjects="S1,S5")


def test_train_classifier_measures_held_out_accuracy(tmp_path):
    model = train_classifier("demo", tmp_path / "clf.pt", actions="walk,run", frames=FRAMES,
                             iters=5, preset="tiny", progress=False)
    loaded = ActionClassifier.load(tmp_path / "clf.pt")
    assert loaded.dataset == "demo" and loaded.split == model.split
    assert 0.0 <= loaded.test_accuracy <= 1.0 and loaded.n_test > 0 and loaded.n_train > loaded.n_test
    confusion = np.array(loaded.test_confusion)
    assert confusion.shape == (2, 2) and confusion.sum() == loaded.n_test
    assert confusion.trace() / loaded.n_test == pytest.approx(loaded.test_accuracy)
    assert loaded.best_iteration == model.best_iteration <= 5 and loaded.n_validation > 0
    assert loaded.history == model.history and loaded.history[-1]["iteration"] == 5


def test_early_stopping_keeps_the_best_validation_state_and_stops_on_patience(clips):
    from motion_metrics.recognition import validation_split

    fitting, checking = validation_split(clips, seed=0)
    assert fitting and checking
    take = lambda c: (c.action, c.meta.get("subject"), c.meta.get("take"))  # noqa: E731
    assert not {take(c) for c in fitting} & {take(c) for c in checking}
    model = ActionClassifier(ClassifierConfig.preset("tiny"), "h36m17", ACTIONS, 25.0, FRAMES)
    model.fit(fitting, 400, seed=0, progress=False, validation=checking, patience=2, eval_every=2)
    history = model.history
    scores = [(h["accuracy"], -h["loss"]) for h in history]
    best = max(range(len(scores)), key=lambda i: scores[i])
    assert history[best]["iteration"] == model.best_iteration
    assert model.validation_accuracy == history[best]["accuracy"]
    # Stopped after 2 measurements in a row without improvement on the best one.
    assert model.stopped_early and model.iteration < 400
    assert len(history) - 1 - best == 2
    # The restored network is the best measured one.
    assert model.accuracy(checking) == pytest.approx(model.validation_accuracy)
    # Deterministic: the same run gives the same history.
    again = ActionClassifier(ClassifierConfig.preset("tiny"), "h36m17", ACTIONS, 25.0, FRAMES)
    again.fit(fitting, 400, seed=0, progress=False, validation=checking, patience=2, eval_every=2)
    assert again.history == history and again.best_iteration == model.best_iteration
    with pytest.raises(ClassifierError, match="validation clips"):
        again.fit(fitting, 2, patience=2)


def test_confusion_counts_true_rows_against_predicted_columns(classifier, clips):
    counts = classifier.confusion(clips)
    assert counts.shape == (3, 3) and counts.sum() == len(clips)
    assert counts.trace() / counts.sum() == pytest.approx(classifier.accuracy(clips))
    assert list(counts.sum(1)) == [sum(c.action == a for c in clips) for a in ACTIONS]


@pytest.mark.parametrize("skeleton", ["h36m17", "h36m15_2d", "smpl24"])
def test_mirroring_swaps_sides_and_is_its_own_inverse(skeleton):
    """A mirror image swaps each left joint with its right one and negates the lateral axis;
    mirroring twice gives the clip back, and rotations keep every distance."""
    from motion_metrics.recognition.augment import Augmenter, mirror_permutation
    from motion.skeletons import get_skeleton

    skel = get_skeleton(skeleton)
    order = mirror_permutation(skel)
    for left, right in zip(skel.left, skel.right):
        assert order[left] == right and order[right] == left
    assert sorted(order) == list(range(skel.n_joints))
    generator = torch.Generator().manual_seed(0)
    inputs = torch.randn(64, 5, skel.n_joints + 1, skel.dims)
    mirror = Augmenter(skel, mirror=True, degrees=0.0)
    once = mirror(inputs, generator)
    flipped = ~torch.isclose(once, inputs).all(dim=(1, 2, 3))
    assert 10 < int(flipped.sum()) < 54  # about half the clips
    # A flipped clip: joints swapped, the lateral axis negated, the others kept.
    i = int(flipped.nonzero()[0])
    lateral = mirror.lateral
    assert torch.allclose(once[i, :, :-1, lateral], -inputs[i][:, order, lateral])
    assert torch.allclose(once[i, :, -1, lateral], -inputs[i, :, -1, lateral])
    rotate = Augmenter(skel, mirror=False, degrees=30.0)
    turned = rotate(inputs, generator)
    assert torch.allclose(turned.norm(dim=-1), inputs.norm(dim=-1), atol=1e-5)
    assert not torch.allclose(turned, inputs)
    if skel.dims == 3:  # about the vertical axis: heights stay
        assert torch.allclose(turned[..., skel.up_index], inputs[..., skel.up_index])


def test_augmented_classifier_trains_saves_and_loads(clips, tmp_path):
    """The temporal convolution beside the GRU and the augmentation are config fields kept
    with the checkpoint; inference does not augment (the same clip, the same features)."""
    config = ClassifierConfig(hidden=16, layers=1, batch_size=16, lr=3e-3, temporal=8,
                              mirror=True, rotate=10.0)
    model = ActionClassifier(config, "h36m17", ACTIONS, 25.0, FRAMES)
    model.fit(clips, 30, seed=0, progress=False)
    assert model.network.convolution is not None
    loaded = ActionClassifier.load(model.save(tmp_path / "augmented.pt"))
    assert loaded.config == config
    assert np.allclose(loaded.features(clips), model.features(clips))
    assert np.allclose(model.features(clips), model.features(clips))
    assert ClassifierConfig.preset("augmented").mirror
    for bad, message in (({"rotate": -1.0}, "rotate must be"), ({"mirror": 1}, "mirror must be"),
                         ({"temporal": 2.5 * -1}, "temporal must be")):
        with pytest.raises(ValueError, match=message):
            ClassifierConfig(**bad)
