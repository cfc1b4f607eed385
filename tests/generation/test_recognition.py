"""The GRU action classifier: training, features, checkpoints, the held-out split."""

import numpy as np
import pytest
import torch

from generation.datasets import get_dataset
from generation.recognition import (
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
