"""The base every rendering style subclasses, and the style registry."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from motion.motion import Motion
from motion.registry import Registry
from rendering.framing import PAD, Framing

_STYLES = Registry("rendering style", package="rendering.styles")


def register_style(name: str):
    """Return a class decorator that registers a :class:`Style` under ``name``."""
    return _STYLES.register(name)


def get_style(name: str) -> type["Style"]:
    """Return a registered style class by name."""
    return _STYLES.get(name)


def list_styles() -> list[str]:
    """Return the names of all registered styles."""
    return _STYLES.names()


class Style:
    """Draw the frames of motions in one framing at one image size.

    One instance renders many clips, so it may build scenery or GL resources once in
    ``__init__``; ``close`` releases them. ``dims`` is the joint dimension it draws;
    ``pad`` how far it draws beyond the joints, per figure height (framings keep room);
    ``player_figure`` the figure the in-browser player draws its clips as (one of
    :data:`rendering.player.FIGURES`), or ``""`` when the player cannot draw them.
    """

    name: str
    dims: int = 3
    pad: float = PAD
    player_figure: str = ""

    def __init__(self, framing: Framing, width: int, height: int):
        self.framing = framing
        self.width = width
        self.height = height

    def reach(self, skeleton: str):
        """Return how far the style draws beyond each joint of ``skeleton``, per figure
        height: one share for all (``pad``) or one per joint (what keeps the figure's
        box inside the frame, :meth:`rendering.framing.Framing.shot`)."""
        return self.pad

    def filmed(self, motion: Motion) -> np.ndarray:
        """Return the joints ``(T, J, 3)`` as this style films them (its shot is worked
        out on these, :meth:`rendering.framing.Framing.shot`): placed by the framing."""
        return self.framing.place(motion)

    def frames(self, motion: Motion) -> Iterator[np.ndarray]:
        """Yield each frame of a motion as ``(H, W, 3)`` uint8 RGB."""
        raise NotImplementedError

    def close(self) -> None:
        """Release what ``__init__`` acquired."""

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()
