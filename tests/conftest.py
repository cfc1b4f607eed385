"""Shared fixtures and factories for every test package."""

import os
from pathlib import Path

import numpy as np
import pytest

from motion.motion import Motion

ROOT = Path(__file__).resolve().parents[1]
SHARED_H36M = (ROOT / ".." / "shared" / "data" / "h36m").resolve()

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")


def make_motion(frames=8, seed=0, skeleton="h36m17", action="walk", source="real", fps=25.0):
    """Return a random-walk motion of a skeleton, for tests that need any motion."""
    from motion.skeletons import get_skeleton

    skel = get_skeleton(skeleton)
    rng = np.random.default_rng(seed)
    base = rng.normal(size=(1, skel.n_joints, skel.dims)) * 0.3
    drift = np.cumsum(rng.normal(scale=0.01, size=(frames, skel.n_joints, skel.dims)), axis=0)
    return Motion(base + drift, skeleton, fps, action, source)


@pytest.fixture
def h36m_root():
    """Return the shared Human3.6M folder, or skip when it is not beside the project."""
    if not (SHARED_H36M / "h36m_positions_25fps.npz").is_file():
        pytest.skip(f"Human3.6M data not found at {SHARED_H36M}")
    return SHARED_H36M


@pytest.fixture(autouse=True)
def _generous_entry_rate_limit(settings):
    """Let tests enrol many participants from 127.0.0.1; the rate-limit test lowers it."""
    settings.STUDY_ENTRY_RATE_LIMIT = "100000/min"
