"""Rendering styles, one module each, found by name through the registry."""

from rendering.styles.base import Style, get_style, list_styles, register_style
from rendering.styles import mesh, stick, stick2d  # noqa: F401  (registers the styles)

__all__ = ["Style", "get_style", "list_styles", "register_style"]
