"""One framing for a set: same camera for all clips, each placed the same way."""

import numpy as np
import pytest

from rendering import Framing
from tests.rendering.conftest import make_figure


def test_one_framing_holds_the_whole_set():
    walker = make_figure(frames=50, speed=2.0)
    stander = make_figure(frames=5)
    framing = Framing.from_motions([walker, stander])
    camera = framing.camera(200, 200)
    for motion in (walker, stander):
        pixels, depth = camera.project(framing.place(motion))
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
