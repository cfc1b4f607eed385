"""One framing for a set: same camera for all clips, each placed the same way."""

import numpy as np
import pytest

from rendering import Framing
from tests.rendering.conftest import make_figure


def test_one_framing_holds_the_whole_set():
    walker = make_figure(frames=50, speed=2.0)
    stander = make_figure(frames=5)
    framing = Framing.from_motions([walker, stander])
    for motion in (walker, stander):
        placed = framing.place(motion)
        for pose, target in zip(placed, framing.targets(motion, placed)):
            pixels, depth = framing.camera(200, 200, target).project(pose)
            assert (depth > 0).all()
            assert (pixels > 10).all() and (pixels < 190).all()


def test_clips_are_placed_alike_whatever_their_coordinates():
    """Moved, turned or lifted copies of a motion are placed identically."""
    motion = make_figure(frames=8, speed=1.0)
    angle = np.radians(70)
    cos, sin = np.cos(angle), np.sin(angle)
    turn = np.array([[cos, -sin, 0], [sin, cos, 0], [0, 0, 1]])
    moved = motion.with_joints(motion.joints @ turn.T + [3.0, -2.0, 0.5])
    framing = Framing.from_motions([motion, moved])
    np.testing.assert_allclose(framing.place(motion), framing.place(moved), atol=1e-5)


def test_set_ground_keeps_floating_visible():
    motion = make_figure(frames=4)
    floating = motion.with_joints(motion.joints + [0.0, 0.0, 0.3])
    framing = Framing.from_motions([motion, floating], ground="set")
    assert framing.place(floating)[..., 2].min() == pytest.approx(0.3, abs=1e-5)
    clip_ground = Framing.from_motions([motion, floating])
    assert clip_ground.place(floating)[..., 2].min() == pytest.approx(0.0, abs=1e-6)


def test_follow_tracks_the_root():
    walker = make_figure(frames=50, speed=2.0)
    framing = Framing.from_motions([walker], follow=True)
    placed = framing.place(walker)
    targets = framing.targets(walker, placed)
    assert np.ptp(targets[:, 1]) > 1.0
    assert np.ptp(targets[:, 2]) == 0.0


def test_mixed_dimensions_are_refused():
    from tests.conftest import make_motion

    with pytest.raises(ValueError, match="all 3D or all 2D"):
        Framing.from_motions([make_motion(skeleton="h36m17"), make_motion(skeleton="h36m15_2d")])


def test_the_scale_comes_from_the_real_clips_only():
    """Catch, example and generated clips in the set change nothing about the camera."""
    real = [make_figure(frames=20, speed=s) for s in (0.0, 1.0)]
    rng = np.random.default_rng(0)
    jittered = real[0].with_joints(real[0].joints + rng.normal(scale=0.4, size=real[0].joints.shape),
                                   source="broken")
    far_walker = make_figure(frames=60, speed=5.0, source="a2m")
    alone = Framing.from_motions(real)
    assert Framing.from_motions(real + [jittered, far_walker]) == alone
    assert alone.follow and alone.target[:2] == (0.0, 0.0)


def test_a_standing_figure_fills_the_share_the_rule_asks():
    stander = make_figure(frames=4)
    for fill in (0.5, 0.65):
        framing = Framing.from_motions([stander], pad=0.0, fill=fill)
        camera = framing.camera(400, 400)
        placed = framing.place(stander)[0]
        pixels, _ = camera.project(placed)
        assert np.ptp(pixels[:, 1]) / 400 == pytest.approx(fill, abs=0.03)
