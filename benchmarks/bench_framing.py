"""The camera rule measured: the figure's share of the frame's height, per style and action.

    .venv/bin/python benchmarks/bench_framing.py           # print the table
    .venv/bin/python benchmarks/bench_framing.py --write   # and update docs/RENDERING.md

Every real clip of the demo dataset is one stimulus set (its framing is fitted on all of
them, as a study's is on its real clips); the walking, sitting-down and jumping clips are
then drawn in each style (``stick2d`` gets them seen from the side, in 2D) with the floor
shadow left out, and the rows where a frame differs from the bare backdrop are the
figure's. A clip's share is the median over its frames (every other frame).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from motion.datasets import get_dataset  # noqa: E402
from motion.skeletons import H36M15_2D_FROM_17  # noqa: E402
from rendering import Framing, get_style  # noqa: E402
from rendering.framing import FILL  # noqa: E402
from rendering.measure import figure_shares  # noqa: E402

DOCS = ROOT / "docs" / "RENDERING.md"
HEADING = "## The figure's share of the frame"
ACTIONS = ("walk", "sit_down", "jump")
STYLES = ("stick", "stick2d", "mesh")


def side_view(motion):
    """Return an ``h36m17`` motion seen from its side as an ``h36m15_2d`` one (pixels)."""
    joints = np.asarray(motion.joints)[:, list(H36M15_2D_FROM_17)]
    pixels = np.stack([joints[..., 0], -joints[..., 2]], axis=-1) * 200.0 + 500.0
    return motion.with_joints(pixels.astype(np.float32), skeleton="h36m15_2d")


def measure(per_action: int, size: int) -> list[dict]:
    clips = get_dataset("demo").clips()
    rows = []
    for style in STYLES:
        motions = [side_view(m) for m in clips] if get_style(style).dims == 2 else clips
        framing = Framing.from_motions(motions, pad=get_style(style).pad)
        for action in ACTIONS:
            chosen = [m for m in motions if m.action == action][:per_action]
            medians, lows, highs, top, bottom, frames = [], [], [], 0, 0, 0
            for motion in chosen:
                shares, (at_top, at_bottom) = figure_shares(style, framing, motion, size,
                                                             every=2)
                medians.append(np.median(shares))
                lows.append(shares.min())
                highs.append(shares.max())
                top, bottom, frames = top + at_top, bottom + at_bottom, frames + len(shares)
            rows.append({"style": style, "action": action, "clips": len(chosen),
                         "median": float(np.median(medians)), "lowest": float(min(medians)),
                         "frame_min": float(min(lows)), "frame_max": float(max(highs)),
                         "top": top, "bottom": bottom, "frames": frames})
    return rows


def section(rows: list[dict], size: int) -> str:
    lines = [
        HEADING,
        "",
        f"`benchmarks/bench_framing.py`: drawn at {size}×{size}; the rule asks a standing "
        f"figure of the set's typical height to fill {FILL:.0%} of the frame.",
        "",
        "| style | action | clips | share, median clip | lowest clip | lowest frame | "
        "highest frame | frames touching the top / bottom edge |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| `{r['style']}` | {r['action']} | {r['clips']} | {r['median']:.2f} | "
                     f"{r['lowest']:.2f} | {r['frame_min']:.2f} | {r['frame_max']:.2f} | "
                     f"{r['top']} / {r['bottom']} of {r['frames']} |")
    lowest = min(r["lowest"] for r in rows)
    lines += ["", f"A clip's share is the median of its frames' shares; the lowest clip's is "
              f"{lowest:.2f} of the frame's height. The share of a clip is the figure's "
              "height in its frames: a seated or crouching figure is shorter than a "
              "standing one, a figure with raised arms taller.", ""]
    return "\n".join(lines)


def write_docs(text: str) -> None:
    current = DOCS.read_text()
    pattern = re.compile(rf"^{re.escape(HEADING)}\n.*?(?=^## |\Z)", re.M | re.S)
    current = pattern.sub(lambda _: text + "\n", current) if pattern.search(current) \
        else current.rstrip("\n") + "\n\n" + text + "\n"
    DOCS.write_text(current)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clips", type=int, default=12, help="clips per action")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--write", action="store_true", help="update docs/RENDERING.md")
    options = parser.parse_args()
    text = section(measure(options.clips, options.size), options.size)
    print(text)
    if options.write:
        write_docs(text)


if __name__ == "__main__":
    main()
