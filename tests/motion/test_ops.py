"""Operations on motions: resampling, trimming, windows, joint selection."""

import numpy as np
import pytest

from motion import ops
from motion.motion import Motion, MotionError
from tests.conftest import make_motion


def ramp(frames, fps=25.0):
    """Return an h36m17 motion whose every coordinate equals its frame number."""
    joints = np.broadcast_to(np.arange(frames, dtype=np.float32)[:, None, None], (frames, 17, 3))
    return Motion(joints.copy(), "h36m17", fps, "walk", meta={"take": "t"})


def test_resample_25_to_50_over_3_interpolates_every_one_and_a_half_frames():
    motion = ops.resample(ramp(7), 50 / 3)
    assert motion.fps == pytest.approx(50 / 3)
    assert motion.frames == ops.resampled_length(7, 25.0, 50 / 3) == 5
    np.testing.assert_allclose(motion.joints[:, 0, 0], [0, 1.5, 3, 4.5, 6], atol=1e-5)
    assert motion.meta == {"take": "t"}


def test_resample_halving_the_rate_keeps_every_second_frame():
    motion = ops.resample(ramp(9, fps=50.0), 25.0)
    np.testing.assert_array_equal(motion.joints[:, 3, 1], [0, 2, 4, 6, 8])


def test_resample_to_the_same_rate_keeps_the_joints():
    motion = make_motion(frames=6)
    same = ops.resample(motion, motion.fps)
    np.testing.assert_array_equal(same.joints, motion.joints)
    with pytest.raises(MotionError):
        ops.resample(motion, 0)


def test_window_starts_default_stride_is_half_a_window():
    assert ops.window_starts(100, 60) == [0, 30]
    assert ops.window_starts(59, 60) == []
    assert ops.window_starts(60, 60, stride=7) == [0]


def test_window_starts_spreads_a_maximum_count_evenly():
    assert ops.window_starts(1000, 10, stride=10, max_count=4) == [120, 370, 620, 870]
    assert ops.window_starts(1000, 10, stride=10, max_count=1) == [500]
    assert ops.window_starts(30, 10, stride=10, max_count=5) == [0, 10, 20]


def test_windows_cut_clips_and_record_their_start():
    clips = ops.windows(ramp(20), 8, stride=5)
    assert [c.meta["start_frame"] for c in clips] == [0, 5, 10]
    assert all(c.frames == 8 and c.meta["take"] == "t" for c in clips)
    assert clips[1].joints[0, 0, 0] == 5
    assert ops.windows(ramp(5), 8) == []


def test_trim_rejects_frames_outside_the_motion():
    with pytest.raises(MotionError, match="10 frames"):
        ops.trim(ramp(10), 5, 6)


def test_select_joints_keeps_the_named_joints_in_order():
    joints = np.arange(4 * 15 * 2, dtype=np.float32).reshape(4, 15, 2)
    motion = Motion(joints, "h36m15_2d", 25.0, "walk")
    order = list(range(14, -1, -1))
    kept = ops.select_joints(motion, order, "h36m15_2d")
    np.testing.assert_array_equal(kept.joints, joints[:, order])
