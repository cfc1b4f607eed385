"""Does every clip's figure stay inside the frame? Before and after ``Framing.shot``.

    .venv/bin/python benchmarks/bench_in_frame.py              # projected boxes, 480 and 128
    .venv/bin/python benchmarks/bench_in_frame.py --rendered   # and stick frames at 128
    .venv/bin/python benchmarks/bench_in_frame.py --player     # and the in-browser player

A demo-like stimulus set: the first four real clips of each of the demo dataset's eight
actions (``--per-action``; 60 frames at 25 fps), a
generated-like version of each (the same clip drifting as generated clips may: a sideways
slide growing to 1.5 m, or a slow rise of 0.6 m, by turns), two catch clips per real
clip (``motion.perturb.catch_family``), a low anchor per real clip and the score-1 to
score-4 scoring-standard examples; one framing fitted on it (the scale from the real
clips). A frame counts as inside when the figure's box, its joints projected with what
the style draws around each (``Style.reach``: the stick figure's balls, the mesh's pad),
lies within the frame; "before" films each clip by the rule's follow camera alone
(``Framing.targets``, rendering VERSION 7), "after" by ``Framing.shot`` (VERSION 8).
``--rendered`` also draws the stick clips at 128×128 and finds the coloured limbs'
pixel box on every other frame (inside: not on the outermost rows or columns).
``--player`` frames each clip as the in-browser player does, from its payload for a
480×480 video as a participant receives it (dithered, quantised: ``rendering.player``),
(the joints as the style films them: the mesh lifts its soles to the floor), its box
projected onto the player's canvas at 480 and at 240 pixels: payload version 1
filmed by the rule's look-at alone ("before"), version 2 by the payload's shot.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from motion import perturb  # noqa: E402
from motion.datasets import get_dataset  # noqa: E402
from motion.skeletons import get_skeleton  # noqa: E402
from rendering import Framing, get_style  # noqa: E402


def drifted(motion, k: int):
    """Return ``motion`` drifting as a generated clip may, labelled ``generated``."""
    t = np.linspace(0.0, 1.0, len(motion.joints))[:, None]
    joints = np.array(motion.joints, dtype=np.float64)
    skeleton = get_skeleton(motion.skeleton)
    if k % 2:
        joints[..., skeleton.up_index] += skeleton.up_sign * 0.6 * t**2  # rising
    else:
        joints[..., 0] += 1.5 * t**3  # sliding sideways, faster and faster
    return motion.with_joints(joints.astype(np.float32), source="generated")


def demo_like(per_action: int = 4, seed: int = 0) -> list:
    real, taken = [], defaultdict(int)
    for clip in get_dataset("demo").clips(frames=60):
        if taken[clip.action] < per_action:
            real.append(clip)
            taken[clip.action] += 1
    rng = np.random.default_rng(seed)
    out = list(real) + [drifted(m, k) for k, m in enumerate(real)]
    out += perturb.catch_family(real, 2, rng)
    out += [perturb.low_anchor(m, rng) for m in real]
    out += [e for m in real for score, e in perturb.standard_examples(m, rng).items() if score < 5]
    return out


def role(motion) -> str:
    return {"broken": "catch", "standard_example": "example"}.get(motion.source, motion.source)


def projected(motions, style: str, size: int) -> dict:
    """Return, per role: frames inside before and after, frames, clips moved, zoomed."""
    framing = Framing.from_motions(motions, pad=get_style(style).pad)
    drawer = get_style(style)(framing, size, size)
    counts = defaultdict(lambda: np.zeros(7))
    for motion in motions:
        reach = drawer.reach(motion.skeleton)
        placed = framing.place(motion)
        low, high = framing._boxes(placed, framing.targets(motion, placed), size, size, reach)
        before = ((low >= 0) & (high <= size)).all(axis=1)
        shot = framing.shot(motion, size, size, reach, placed)
        low, high = shot.framing._boxes(placed, shot.targets, size, size, reach)
        low, high = low - shot.offsets, high - shot.offsets
        after = ((low >= 0) & (high <= size)).all(axis=1)
        zoom = shot.framing.distance / framing.distance
        counts[role(motion)] += [before.sum(), after.sum(), len(before),
                                 int(shot.offsets.any()), int(shot.framing != framing), 1, 0]
        counts[role(motion)][6] = max(counts[role(motion)][6], zoom)
    drawer.close()
    return counts


def player(motions, style: str, size: int = 480, canvases=(480, 240)) -> dict:
    """Return, per role: frames inside the player's canvas of ``size`` pixels as payload
    version 1 framed them (the rule's look-at alone), inside its canvas of each size now
    (payloads made for ``size``-pixel videos and dithered as delivered), and frames."""
    from rendering.player import dither, payload, read

    framing = Framing.from_motions(motions, pad=get_style(style).pad)
    drawer = get_style(style)(framing, size, size)
    rng = np.random.default_rng(1)
    counts = defaultdict(lambda: np.zeros(len(canvases) + 2))
    for motion in motions:
        reach = drawer.reach(motion.skeleton)
        fields = read(dither(payload(motion, framing, size, reach, drawer.filmed(motion)), rng))
        placed = framing.place(motion)
        low, high = framing._boxes(placed, framing.targets(motion, placed), size, size, reach)
        row = [((low >= 0) & (high <= size)).all(axis=1).sum()]
        for canvas in canvases:
            inside = 0
            for distance in np.unique(fields["distances"]):  # dithered: a unit either way
                at = fields["distances"] == distance
                filmed = framing._with(distance=float(distance))
                low, high = filmed._boxes(fields["positions"][at], fields["targets"][at],
                                          canvas, canvas, reach)
                shift = fields["windows"][at] * canvas
                low, high = low - shift, high - shift
                inside += ((low >= 0) & (high <= canvas)).all(axis=1).sum()
            row.append(inside)
        counts[role(motion)] += [*row, len(fields["positions"])]
    drawer.close()
    return counts


def rendered(motions, size: int = 128, every: int = 2) -> dict:
    from tests.rendering.helpers import figure_box

    framing = Framing.from_motions(motions)
    counts = defaultdict(lambda: np.zeros(2, int))
    with get_style("stick")(framing, size, size) as drawer:
        for motion in motions:
            for number, frame in enumerate(drawer.frames(motion)):
                if number % every:
                    continue
                box = figure_box(frame)
                inside = box is not None and min(box[:2]) >= 1 and max(box[2:]) <= size - 2
                counts[role(motion)] += [int(inside), 1]
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rendered", action="store_true")
    parser.add_argument("--player", action="store_true")
    parser.add_argument("--per-action", type=int, default=4, help="real clips per action")
    args = parser.parse_args()
    motions = demo_like(args.per_action)
    print(f"{len(motions)} clips", flush=True)
    print("| style | size | role | clips | frames inside, before | after | clips whose window "
          "moves | clips zoomed out | farthest zoom |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for style in ("stick", "mesh"):
        for size in (480, 128):
            for name, (before, after, frames, moved, zoomed, clips, zoom) in sorted(
                    projected(motions, style, size).items()):
                print(f"| `{style}` | {size} | {name} | {clips:.0f} | {before / frames:.3f} | "
                      f"{after / frames:.3f} | {moved:.0f} | {zoomed:.0f} | {zoom:.2f} |",
                      flush=True)
    if args.player:
        print("\nthe in-browser player, payloads for 480x480 videos: share of frames inside")
        print("| style | role | clips | version 1, canvas 480 | version 2, canvas 480 | "
              "canvas 240 |")
        print("|---|---|---:|---:|---:|---:|")
        for style in ("stick", "mesh"):
            for name, (old, at480, at240, frames) in sorted(player(motions, style).items()):
                print(f"| `{style}` | {name} | {frames / 60:.0f} | {old / frames:.3f} | "
                      f"{at480 / frames:.3f} | {at240 / frames:.3f} |", flush=True)
    if args.rendered:
        print("\nrendered, stick at 128x128, every other frame: share of frames inside")
        for name, (inside, frames) in sorted(rendered(motions).items()):
            print(f"{name}: {inside}/{frames} = {inside / frames:.3f}")


if __name__ == "__main__":
    main()
