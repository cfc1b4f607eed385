"""The camera rule: the body fills at least half of the frame's height in every style.

Measured on drawn frames of the demo dataset's walking, sitting and jumping clips, in the
framing a study fits on its real clips (every action), with shadows left out so that only
the body counts.
"""

import numpy as np
import pytest

from motion.datasets import get_dataset
from rendering import Framing, get_style
from rendering.measure import figure_shares
from tests.rendering.helpers import to_2d

SIZE = 128
ACTIONS = ("walk", "sit_down", "jump")
STYLES = ("stick", "stick2d", "mesh")


@pytest.fixture(scope="module")
def demo_clips():
    return get_dataset("demo").clips()


def _study_set(clips, style):
    """Return every real demo clip a style draws: the set its framing is fitted on."""
    return [to_2d(m) for m in clips] if get_style(style).dims == 2 else list(clips)


@pytest.mark.slow
@pytest.mark.parametrize("style", STYLES)
def test_the_body_fills_half_the_frame_in_every_style(style, demo_clips):
    motions = _study_set(demo_clips, style)
    framing = Framing.from_motions(motions, pad=get_style(style).pad)
    for action in ACTIONS:
        motion = next(m for m in motions if m.action == action)
        shares, (top, bottom) = figure_shares(style, framing, motion, SIZE, every=2)
        assert np.median(shares) >= 0.5, f"{style} {action}: {np.median(shares):.2f}"
        assert shares.max() < 0.95, f"{style} {action}: the camera is too close"
        assert bottom == 0, f"{style} {action}: the feet leave the frame"
        if action != "jump":  # raised hands may reach the top at a jump's peak
            assert top == 0, f"{style} {action}: the figure leaves the frame"
