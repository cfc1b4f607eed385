"""Catch clips: broken by turning whole bones (every bone keeps its length in every frame),
as smooth as their base, and each kind broken in a way one can measure."""

import numpy as np
import pytest

from motion import perturb
from motion.datasets import get_dataset
from generation.sampling import sample_real
from motion.skeletons import get_skeleton
from tests.rendering.conftest import make_figure
from tests.rendering.helpers import to_2d


@pytest.fixture(scope="module")
def demo():
    """Real demo clips: one of every action (h36m17, metres, z up)."""
    return {m.action: m for m in sample_real(get_dataset("demo"), None, 1, None, 5)}


def bases(demo):
    walker = make_figure("humanact12", frames=40, speed=1.4)  # y up, SMPL's 24 joints
    return list(demo.values()) + [walker, to_2d(demo["walk"])]


def jerk(joints, fps):
    return np.linalg.norm(np.diff(joints.astype(float), 3, axis=0), axis=-1) * fps ** 3


@pytest.mark.parametrize("kind", list(perturb.KINDS))
def test_every_kind_keeps_every_bone_and_the_motions_smoothness(demo, kind):
    rng = np.random.default_rng(0)
    tried = 0
    for base in bases(demo):
        if kind not in perturb.kinds_for(base):
            continue
        tried += 1
        broken = perturb.broken(base, kind, rng)
        skeleton = get_skeleton(base.skeleton)
        before, after = (skeleton.bone_lengths(m.joints.astype(float)) for m in (base, broken))
        assert np.abs(after - before).max() <= 1e-5 * perturb.extent(base), base.action
        assert broken.source == "broken" and broken.meta["broken"] == kind
        assert broken.frames == base.frames and np.isfinite(broken.joints).all()
        assert not np.allclose(broken.joints, base.joints, atol=1e-3 * perturb.extent(base))
        # No jolt where a bone turns: a turned limb may move further than before (a
        # squat's feet bent forwards swing), never by a jump.
        scale = perturb.extent(base) * base.fps ** 3 * 1e-3
        for q in (95, 100):
            assert np.percentile(jerk(broken.joints, base.fps), q) <= \
                5.0 * np.percentile(jerk(base.joints, base.fps), q) + scale, (kind, base.action)
    assert tried >= 2, f"{kind} fits too few bases to test"


def _angle(a, b):
    cos = (a * b).sum(-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def test_each_kind_is_broken_in_the_way_it_says(demo):
    rng = np.random.default_rng(1)
    walk = demo["walk"]
    body = perturb.Body.of(walk)
    up = body.up
    down = -up

    bent = perturb.broken(walk, "bent_backwards", rng).joints.astype(float)
    directions, _ = perturb._bones(walk.joints.astype(float), body.parents)
    axis = perturb._lateral(walk.joints.astype(float), body, walk.fps)
    after, _ = perturb._bones(bent, body.parents)
    for limb in perturb._bending(walk.joints.astype(float), body, walk.fps):
        usual = np.median(perturb._flexion(directions, limb, axis))
        now = perturb._flexion(after, limb, perturb._lateral(bent, body, walk.fps))
        # Bent the other way, always at least the extra bend's 15 degrees.
        assert (np.sign(now) == -np.sign(usual)).mean() > 0.95
        assert np.degrees(np.abs(now)).min() > 14

    out = perturb.broken(walk, "leg_out", rng).joints.astype(float)
    turned = [leg for leg in body.legs if not np.allclose(out[:, leg.lower], walk.joints[:, leg.lower], atol=1e-3)]
    assert len(turned) == 1
    thigh = out[:, turned[0].middle] - out[:, turned[0].upper]
    assert np.median(_angle(thigh, down)) > 60  # held out, far from hanging down

    swapped = perturb.broken(walk, "limbs_swapped", rng).joints.astype(float)
    for arm in body.arms:  # the hands stride above the shoulders
        assert ((swapped[:, arm.lower] - swapped[:, arm.upper]) @ up > 0).mean() > 0.9

    hanging = perturb.broken(walk, "head_hanging", rng).joints.astype(float)
    base_joint, neck = body.head
    top = [j for j in body.below[neck]]
    assert ((hanging[:, top] @ up).max(axis=1) < hanging[:, base_joint] @ up).all()

    leaning = perturb.broken(walk, "leaning", rng).joints.astype(float)
    trunk = leaning[:, base_joint] - leaning[:, body.order[0]]
    tilt = _angle(trunk, np.broadcast_to(up, trunk.shape))
    assert tilt.min() > 30

    sliding = perturb.broken(walk, "sliding", rng).joints.astype(float)
    leg = body.legs[0]
    knee_angle = _angle(sliding[:, leg.middle] - sliding[:, leg.upper],
                        sliding[:, leg.lower] - sliding[:, leg.middle])
    assert np.ptp(knee_angle) < 1.0  # the legs hold one pose ...
    root = sliding[:, body.order[0]]
    assert perturb._travel(sliding, body, perturb.extent(walk)) >= perturb.SLIDE_TRAVEL  # ... and glide


def test_sliding_needs_a_base_that_travels(demo):
    assert "sliding" in perturb.kinds_for(demo["walk"])
    assert "sliding" not in perturb.kinds_for(demo["wave"])
    with pytest.raises(KeyError, match="no kind of break 'shaken'"):
        perturb.broken(demo["walk"], "shaken", np.random.default_rng(0))


def test_a_catch_family_spreads_kinds_and_keeps_the_numbers_near_the_base(demo):
    family = perturb.catch_family(list(demo.values()), 2, np.random.default_rng(2))
    assert len(family) == 2 * len(demo)
    for k in range(0, len(family), 2):  # two kinds per base
        assert family[k].meta["broken"] != family[k + 1].meta["broken"]
        assert family[k].action == family[k + 1].action
    assert len({m.meta["broken"] for m in family}) >= 4
    again = perturb.catch_family(list(demo.values()), 2, np.random.default_rng(2))
    assert all(np.array_equal(a.joints, b.joints) for a, b in zip(family, again))
    for motion in family:
        base = demo[motion.action]
        body = perturb.Body.of(base)
        near = perturb._unlike(perturb.profile(motion.joints.astype(float), body, base.fps),
                               perturb.profile(base.joints.astype(float), body, base.fps))
        assert near <= max(perturb.NEAR, 0.5), motion.meta["broken"]


def test_broken_clips_drop_an_imported_body_surface(demo):
    walk = demo["walk"]
    vertices = np.zeros((walk.frames, 3, 3), np.float32)
    dressed = walk.with_joints(walk.joints, vertices=vertices, faces=np.array([[0, 1, 2]]))
    broken = perturb.catch_clip(dressed, np.random.default_rng(0))
    assert broken.vertices is None and broken.faces is None


def test_examples_and_anchors_are_still_shaken(demo):
    walk = demo["walk"]
    examples = perturb.standard_examples(walk, np.random.default_rng(0))
    assert sorted(examples) == [1, 2, 3, 4, 5]
    assert np.array_equal(examples[5].joints, walk.joints)
    spread = [np.abs(examples[s].joints - walk.joints).mean() for s in (4, 3, 2, 1)]
    assert spread == sorted(spread)
    anchor = perturb.low_anchor(walk, np.random.default_rng(0))
    assert anchor.source == "anchor" and not np.allclose(anchor.joints, walk.joints)
