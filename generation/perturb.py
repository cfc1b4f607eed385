"""Motion operations that make a clip worse on purpose: the broken clips of attention
checks (catch trials), the graded examples of a scoring standard and the low anchors of
MUSHRA-style trials. Each returns a new motion; the input is left alone.

The size of a perturbation is a share of the figure's size (the largest side of the box
around its joints in a frame, the median over the clip), so it means the same on any
skeleton and unit, and a clip that travels far is not shaken further than one that
stays put.
"""

from __future__ import annotations

import numpy as np

from generation.motion import Motion

# Joint jitter, as a share of the figure's extent, of the example clip of each score of
# a five-step scoring standard; the catch clip is broken further still.
STANDARD_NOISE = {5: 0.0, 4: 0.01, 3: 0.03, 2: 0.07, 1: 0.18}
CATCH_NOISE = 0.25
ANCHOR_NOISE = 0.12


def extent(motion: Motion) -> float:
    """Return the figure's size: the largest side of the box around its joints in a frame,
    the median over the clip's frames."""
    per_frame = np.ptp(motion.joints, axis=1).max(axis=1)  # (T,)
    return float(np.median(per_frame))


def jitter(motion: Motion, noise: float, rng, source: str | None = None) -> Motion:
    """Return ``motion`` with each joint of each frame moved by Gaussian noise of
    ``noise`` x the figure's size (0 leaves it as is), labelled ``source`` when given."""
    joints = motion.joints
    shake = rng.normal(scale=noise * extent(motion), size=joints.shape) if noise > 0 else 0.0
    moved = (joints + shake).astype(np.float32)
    return motion.with_joints(moved, source=source or motion.source, meta=dict(motion.meta))


def catch_clip(motion: Motion, rng, source: str = "broken") -> Motion:
    """Return the obviously broken version of a real clip shown in catch trials."""
    return jitter(motion, CATCH_NOISE, rng, source)


def standard_examples(motion: Motion, rng, source: str = "standard_example") -> dict:
    """Return ``{score: motion}``: one clip per score of a scoring standard, from
    ``motion`` as is (5) to badly broken (1)."""
    return {score: jitter(motion, noise, rng, source)
            for score, noise in sorted(STANDARD_NOISE.items())}


def low_anchor(motion: Motion, rng, source: str = "anchor") -> Motion:
    """Return a clearly degraded version of a real clip: the low anchor of MUSHRA trials."""
    return jitter(motion, ANCHOR_NOISE, rng, source)
