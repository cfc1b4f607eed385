"""Render motions to videos: styles by name, one framing per stimulus set.

Plain numpy, Pillow and OpenCV (the mesh style adds pyrender, imported when first drawn);
never Django or torch.
"""

from rendering.batch import (
    VERSION,
    RenderedClip,
    RenderError,
    RenderReport,
    render_clip,
    render_motion,
    render_set,
    resample,
)
from rendering.framing import Framing
from rendering.grid import RenderedGrid, render_grid
from rendering.styles import Style, get_style, list_styles, register_style
from rendering.video import FORMATS

__all__ = [
    "FORMATS",
    "Framing",
    "RenderError",
    "RenderReport",
    "RenderedClip",
    "RenderedGrid",
    "Style",
    "get_style",
    "list_styles",
    "register_style",
    "render_clip",
    "render_grid",
    "render_motion",
    "render_set",
    "resample",
    "VERSION",
]
