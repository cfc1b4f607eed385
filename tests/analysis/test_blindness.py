"""The blindness audit's classifier and the file features it reads."""

import numpy as np

from analysis.blindness import audit, clip_features, mp4_features


def test_features_that_do_not_differ_cannot_tell_clips_apart():
    rows = [{"video_bytes": 1000.0, "width": 480.0} for _ in range(40)]
    result = audit(rows, [i % 3 == 0 for i in range(40)])
    assert result["passed"] and result["accuracy"] <= result["chance"] + 1e-9


def test_a_feature_that_follows_the_label_is_caught():
    rng = np.random.default_rng(0)
    labels = [i % 2 == 0 for i in range(40)]
    rows = [{"video_bytes": 31_000.0 + (0 if real else 5000) + rng.normal(0, 800)}
            for real in labels]
    result = audit(rows, labels)
    assert not result["passed"] and result["accuracy"] > 0.9


def test_noise_alone_does_not_fail_the_audit():
    rng = np.random.default_rng(1)
    failures = 0
    for seed in range(20):
        rows = [{"a": float(v), "b": float(w)} for v, w in rng.normal(size=(48, 2))]
        failures += not audit(rows, [i % 3 == 0 for i in range(48)], seed=seed)["passed"]
    assert failures <= 1  # the margin is one-sided 99 %


def test_too_few_clips_of_a_kind_is_nothing_to_tell_apart():
    result = audit([{"a": 1.0}, {"a": 2.0}, {"a": 3.0}], [True, False, False])
    assert result["passed"] and result["accuracy"] is None


def test_mp4_features_read_duration_size_and_frames(tmp_path):
    from tests.studyapp.conftest import FPS, FRAMES, SIZE, write_clip

    path = tmp_path / "clip.mp4"
    write_clip(path, (40, 90, 140))
    data = path.read_bytes()
    features = mp4_features(data)
    assert abs(features["duration_s"] - FRAMES / FPS) < 0.05
    assert (features["width"], features["height"]) == (SIZE, SIZE)
    assert features["frames"] == FRAMES and features["frame_bytes_mean"] > 0
    assert features["box_mdat_bytes"] > 0 and features["box_moov_bytes"] > 0
    every = clip_features(data, {"Content-Length": str(len(data)), "Date": "now"})
    assert every["video_content_length"] == len(data)
    assert "video_h_date_len" not in every  # the moment, not the clip
