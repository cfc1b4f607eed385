"""Every registered style draws a tiny clip of a skeleton it supports."""

import subprocess
import sys

import numpy as np
import pytest

from generation.skeletons import get_skeleton, list_skeletons
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
