"""The colours every style shares: warm left, cool right, neutral centre, quiet scenery."""

import numpy as np

LEFT = np.array([236.0, 112.0, 52.0])  # warm orange
RIGHT = np.array([46.0, 118.0, 214.0])  # cool blue
CENTRE = np.array([132.0, 138.0, 150.0])  # slate grey

SKY_TOP = np.array([250.0, 250.0, 251.0])
SKY_HORIZON = np.array([229.0, 232.0, 237.0])
FLOOR_LIGHT = np.array([222.0, 225.0, 230.0])
FLOOR_DARK = np.array([206.0, 210.0, 217.0])
SHADOW = (92, 98, 110)

WHITE = np.array([255.0, 255.0, 255.0])


def side_colour(side: str) -> np.ndarray:
    """Return the colour of a joint side (``"left"``, ``"right"`` or ``"centre"``)."""
    return {"left": LEFT, "right": RIGHT}.get(side, CENTRE)
