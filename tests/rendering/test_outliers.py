"""Joints flung at or behind the camera (a broken catch clip can do it) render quickly."""

import signal

import numpy as np
import pytest

from rendering import Framing, get_style
from tests.rendering.conftest import make_figure


@pytest.fixture
def deadline():
    """Fail instead of hanging: drawing a point at the eye once took forever."""
    def expire(*_):
        raise TimeoutError("a frame took more than 20 s to draw")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("style", ["stick", "mesh"])
def test_a_joint_behind_the_eye_is_left_out(style, deadline):
    motion = make_figure(frames=3, speed=1.0)
    framing = Framing.from_motions([motion])
    joints = motion.joints.copy()
    joints[1, 10] += np.array([3.0, -3.3, 1.0])  # the head of frame 1, past the camera
    broken = motion.with_joints(joints, source="broken")
    placed = framing.place(broken)
    camera = framing.camera(96, 96, framing.targets(broken, placed)[1])
    assert camera.project(placed[1])[1].min() < 0, "the joint should be behind the eye"
    with get_style(style)(framing, 96, 96) as drawer:
        frames = list(drawer.frames(broken))
    assert len(frames) == 3 and all(f.std() > 3 for f in frames)
