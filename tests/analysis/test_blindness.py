"""The blindness audit's statistics, the features a script reads of the files, and the
attacks it must see: a payload-statistics classifier of shaken catch clips, padding
sizes that follow the content, deliveries that share bytes."""

import numpy as np
import pytest

from analysis.blindness import ClipRecord, delivery_check, leak_test, verdict
from analysis.clip_features import (bitstream_features, content_keys, delivery_features,
                                    mp4_features, payload_features, same_content)


def test_features_that_do_not_differ_cannot_tell_clips_apart():
    rows = [{"video_bytes": 1000.0, "width": 480.0} for _ in range(40)]
    result = leak_test(rows, [i % 3 == 0 for i in range(40)], permutations=200)
    assert not result["significant"] and result["p_value"] == 1.0
    assert result["auc"] == 0.5


def test_a_feature_that_follows_the_label_is_caught_and_named():
    rng = np.random.default_rng(0)
    labels = [i % 2 == 0 for i in range(40)]
    rows = [{"video_bytes": 31_000.0 + (0 if real else 5000) + rng.normal(0, 800),
             "noise": rng.normal()} for real in labels]
    result = leak_test(rows, labels, permutations=500)
    assert result["significant"] and result["auc"] > 0.95
    assert result["best_feature"] == "video_bytes" and result["accuracy"] > 0.9
    # Outliers on both sides (a spread, not a shift) are caught too: the squares.
    spread = [{"a": rng.normal(0, 3 if label else 1)} for label in labels * 2]
    assert leak_test(spread, labels * 2, permutations=500)["significant"]


def test_noise_alone_fails_about_as_often_as_alpha_says():
    rng = np.random.default_rng(1)
    failures = 0
    for seed in range(30):
        rows = [{"a": float(v), "b": float(w), "c": float(u)} for v, w, u in rng.normal(size=(48, 3))]
        failures += leak_test(rows, [i % 3 == 0 for i in range(48)], alpha=0.05,
                              permutations=200, seed=seed)["significant"]
    assert failures <= 5  # 30 x 5 % is 1.5; the test is exact, so rarely more


def test_with_few_clips_it_says_only_a_large_leak_could_show():
    rng = np.random.default_rng(2)
    few = leak_test([{"a": rng.normal()} for _ in range(8)], [True, False] * 4, alpha=0.002,
                    permutations=500)
    many = leak_test([{"a": rng.normal()} for _ in range(200)], [True, False] * 100,
                     alpha=0.002, permutations=500)
    assert few["too_few"] and few["detectable_auc"] > 0.9
    assert not many["too_few"] and many["detectable_auc"] < 0.7
    assert "too few clips to tell a smaller one" in verdict("source", "delivery", few)["says"]
    nothing = leak_test([{"a": 1.0}, {"a": 2.0}, {"a": 3.0}], [True, False, False])
    assert nothing["auc"] is None and verdict("catch", "payload", nothing)["passed"]


def test_content_tells_the_source_without_failing_but_must_not_tell_catch_clips():
    leak = {"auc": 0.99, "p_value": 0.0005, "significant": True, "n": 48, "positives": 16,
            "best_feature": "true_frame_bytes_sd", "best_auc": 0.99, "detectable_auc": 0.8,
            "too_few": False}
    source = verdict("source", "bitstream", leak)
    assert source["passed"] and source["kind"] == "content"
    assert source["says"].startswith("content: a script that parses the H.264 bitstream")
    assert "as a viewer of the motion could" in source["says"]
    catch = verdict("catch", "payload", leak)
    assert not catch["passed"] and "pass attention checks without watching" in catch["says"]
    assert not verdict("source", "delivery", leak)["passed"]


def test_a_deep_audit_fails_a_leak_only_when_a_second_delivery_repeats_it(monkeypatch):
    """What each delivery lays out anew can separate catch clips by chance in one delivery
    (its draws); a leak must show in the second delivery too. A leak that follows the clip
    shows in both and fails."""
    import analysis.blindness as blindness
    monkeypatch.setattr(blindness, "features", lambda files: files)
    for check in ("delivery_check", "content_check"):  # of the files' bytes: none here
        monkeypatch.setattr(blindness, check, lambda clips: {"passed": True})
    rng = np.random.default_rng(4)
    roles = ["catch"] * 8 + ["judged"] * 16

    def clips(first, second):
        return [ClipRecord(role, "real" if k % 2 else "a2m",
                           [{"delivery": {"units": float(a)}, "bitstream": {}, "payload": {}},
                            {"delivery": {"units": float(b)}, "bitstream": {}, "payload": {}}])
                for k, (role, a, b) in enumerate(zip(roles, first, second))]

    lucky = np.where(np.array(roles) == "catch", 1.0, 0.0) + rng.normal(0, 0.1, 24)
    chance = blindness.assess(clips(lucky, rng.normal(size=24)), permutations=400)
    assert chance["catch: delivery"]["passed"]
    assert "the larger of 2 deliveries' p" in chance["catch: delivery"]["says"]
    basic = blindness.assess(clips(lucky, rng.normal(size=24)), deep=False, permutations=400)
    assert not basic["catch: delivery"]["passed"]  # one delivery cannot tell chance from leak
    leak = blindness.assess(clips(lucky, lucky + rng.normal(0, 0.1, 24)), permutations=400)
    assert not leak["catch: delivery"]["passed"]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from rendering import Framing, render_set
    from rendering.player import payload
    from tests.rendering.conftest import make_figure

    walker = make_figure(frames=20, speed=1.5)
    still = walker.with_joints(np.repeat(walker.joints[:1], 20, axis=0))
    report = render_set([walker, still], tmp_path_factory.mktemp("features"), size=96,
                        progress=False)
    framing = Framing.from_motions([walker, still])
    return [{"mp4": ({"Content-Length": "1", "Date": "now"}, c.video.read_bytes()),
             "png": ({}, c.poster.read_bytes()), "motion": ({}, payload(m, framing))}
            for c, m in zip(report.clips, (walker, still))]


def test_the_files_show_one_size_and_table_but_a_parser_reads_true_frame_sizes(rendered):
    from rendering.delivery import deliver

    walker, still = rendered
    first = mp4_features(walker["mp4"][1])
    assert first == mp4_features(still["mp4"][1])  # padded: one layout, one stsz table
    assert first["frames"] == 20 and first["frame_bytes_sd"] > 0  # a keyframe, then frames
    every = delivery_features(walker)
    assert "video_h_date_len" not in every  # the moment, not the clip
    true = [bitstream_features(files) for files in rendered]
    assert true[0]["true_frame_bytes_mean"] > 1.2 * true[1]["true_frame_bytes_mean"]
    assert true[0]["poster_image_bytes"] != true[1]["poster_image_bytes"]
    # A delivery's new filler layout changes no true size, and no content key.
    seed = bytes(range(32))
    moved = {ext: (headers, deliver(body, ext, seed)) for ext, (headers, body) in walker.items()}
    assert bitstream_features(moved) == true[0]
    keys, again = content_keys(walker), content_keys(moved)
    assert all(same_content(ext, keys[ext], again[ext]) for ext in keys)
    assert not same_content("motion", keys["motion"], content_keys(still)["motion"])
    speeds = [payload_features(files)["speed_mean"] for files in rendered]
    assert speeds[0] > 1.0 > 0.01 > speeds[1]


def test_deliveries_that_share_bytes_fail_and_their_own_bytes_pass(rendered):
    from rendering.delivery import deliver

    def record(files_list):
        return ClipRecord("judged", "real", files_list)

    same = delivery_check([record([rendered[0], rendered[0]]), record([rendered[1]])])
    assert not same["passed"] and same["repeated_bytes"] == 3
    assert "recognises a repeated trial's clip" in same["says"]
    own = [record([{ext: ({"ETag": f'"{c}{k}-{ext}"'}, deliver(body, ext, bytes([k]) * 32))
                    for ext, (_, body) in files.items()} for k in range(2)])
           for c, files in enumerate(rendered)]
    assert delivery_check(own)["passed"]
    tags = [record([{ext: ({"ETag": '"one"'}, body) for ext, (_, body) in f.items()}])
            for f in own[0].deliveries]
    assert delivery_check(tags)["repeated_etags"] > 0


@pytest.fixture(scope="module")
def demo_payloads():
    """Judged clips of the demo's three sources and, per action, a base clip of each
    source the catch clips are made from: their payloads in one framing."""
    from motion import ops
    from motion.datasets import get_dataset
    from generation.sampling import sample_method, sample_real
    from rendering import Framing
    from tests.conftest import ROOT

    dataset = get_dataset("demo")
    drawn = {"real": sample_real(dataset, None, 3, None, 0)}
    for method in ("a2m", "cond_gru"):
        drawn[method] = sample_method(ROOT / "studies" / "demo" / "checkpoints" / f"{method}.pt",
                                      None, 3, 60, 0, method)
    judged, bases = [], []
    for motions in drawn.values():
        for action in dataset.actions():
            mine = [m for m in motions if m.action == action]
            judged += mine[:2]
            bases.append(mine[2])
    framing = Framing.from_motions([ops.canonical(m, 3) for m in drawn["real"]])
    return judged, bases, framing


def _payload_rows(motions, framing):
    from motion import ops
    from rendering.player import payload

    return [payload_features({"motion": ({}, payload(ops.canonical(m, 3), framing))})
            for m in motions]


def test_a_payload_statistics_classifier_tells_shaken_catch_clips_but_not_the_family(
        demo_payloads):
    """The attack: a script reads the player's joints and picks the clip whose bones
    stretch (shaken catch clips: bone lengths varying 41 %, judged at most 21 %). The
    catch family, broken by turning whole bones, is not told from the judged clips."""
    from motion import perturb

    judged, bases, framing = demo_payloads
    rng = np.random.default_rng(0)
    shaken = [perturb.jitter(m, 0.25, rng, "broken") for m in bases]
    by_action = {}
    for base in bases:
        by_action.setdefault(base.action, []).append(base)
    family = [m for group in by_action.values() for m in perturb.catch_family(group, 2, rng)]
    rows = _payload_rows(judged, framing)
    alpha = 0.01 / 5  # as the deep audit's share of its error rate
    old = leak_test(rows + _payload_rows(shaken, framing),
                    [False] * len(judged) + [True] * len(shaken), alpha=alpha)
    assert old["significant"] and old["auc"] > 0.99
    new = leak_test(rows + _payload_rows(family, framing),
                    [False] * len(judged) + [True] * len(family), alpha=alpha)
    assert len(family) == len(judged) == 48
    assert not new["significant"], new
    assert new["best_auc"] < 0.7  # no single number gives them away
