"""Rendering styles, one module each, found by name through the registry."""

from rendering.styles.base import Style, get_style, list_styles, register_style

__all__ = ["Style", "get_style", "list_styles", "register_style"]
