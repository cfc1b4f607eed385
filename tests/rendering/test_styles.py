"""Every registered style draws a tiny clip of a skeleton it supports."""

import subprocess
import sys

import numpy as np
import pytest

from motion.skeletons import get_skeleton, list_skeletons
from rendering import Framing, Style, get_style, list_styles, register_style
from tests.conftest import ROOT, make_motion


def _skeleton_for(style: type[Style]) -> str:
    return next(name for name in list_skeletons() if get_skeleton(name).dims == style.dims)


@pytest.mark.parametrize("name", list_styles())
def test_style_draws_frames_of_its_size(name):
    style = get_style(name)
    motion = make_motion(frames=3, skeleton=_skeleton_for(style))
    with style(Framing.from_motions([motion]), 64, 48) as drawer:
        frames = list(drawer.frames(motion))
    assert len(frames) == 3
    for frame in frames:
        assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8
        assert frame.std() > 5


def test_registry_lists_and_rejects():
    assert {"stick", "stick2d"} <= set(list_styles())
    assert get_style("stick").name == "stick"
    with pytest.raises(KeyError, match="stick"):
        get_style("no_such_style")
    with pytest.raises(ValueError, match="already registered"):
        register_style("stick")(type("Again", (Style,), {}))


def test_rendering_imports_neither_torch_nor_django():
    """Rendering runs in workers and jobs that must stay light."""
    code = "import sys, rendering; print(' '.join(m.split('.')[0] for m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert not {"torch", "django"} & set(result.stdout.split())


def test_stick_shapes_reaching_far_beyond_the_frame_are_cut_not_bent():
    """A tube from inside the frame to a point far outside it (a joint near the eye)
    keeps its direction on screen: it is cut at a guard around the frame, not squashed."""
    import cv2

    from rendering.styles.stick import SHIFT, _shapes

    direction = np.array([0.6, 0.8])
    across = np.array([-0.8, 0.6]) * 3.0
    images = []
    for reach in (400.0, 1e7):  # the far end just past the frame, and far beyond the guard
        start, end = np.array([40.0, 30.0]), np.array([40.0, 30.0]) + direction * reach
        band = np.array([[start + across, end + across, end - across, start - across]])
        fixed, cut = _shapes(band, (96, 96))
        shape = cut.get((0,), fixed[0])
        image = np.zeros((96, 96), np.uint8)
        cv2.fillConvexPoly(image, shape, 255, cv2.LINE_AA, SHIFT)
        images.append(image.astype(int))
    assert images[0].sum() > 255 * 200
    assert np.abs(images[0] - images[1]).max() <= 2


def test_the_stick_backdrop_is_lighter_than_the_shadow_everywhere():
    """The shadow is blended in unsigned bytes (stick._darken): every backdrop colour must
    be lighter than the shadow colour in every channel, or the shadow would vanish there."""
    from rendering import palette

    framing = Framing.from_motions([make_motion(frames=4)], pad=get_style("stick").pad)
    backdrop = get_style("stick")(framing, 96, 96)._backdrop
    darkest = np.minimum(backdrop.image(None).min(axis=(0, 1)),
                         backdrop.image(np.asarray(framing.target) + 0.3).min(axis=(0, 1)))
    assert (darkest > np.array(palette.SHADOW)).all(), darkest


@pytest.mark.parametrize("name", list_styles())
def test_a_style_declares_its_dimensions_and_the_figure_the_in_browser_player_draws(name):
    from rendering.player import FIGURES

    style = get_style(name)
    assert style.dims in (2, 3)
    assert style.player_figure in FIGURES + ("",)
    assert not style.player_figure or style.dims == 3  # the player draws 3D figures
