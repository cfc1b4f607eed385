"""Stick figures of 2D skeletons (image coordinates), seen flat on a clean background."""

from rendering.styles.base import register_style
from rendering.styles.stick import StickStyle


@register_style("stick2d")
class Stick2DStyle(StickStyle):
    """2D skeletons drawn like ``stick``, without floor or shadow (their depth is unknown)."""

    dims = 2
    shadow = False
    player_figure = ""  # the in-browser player draws 3D figures
