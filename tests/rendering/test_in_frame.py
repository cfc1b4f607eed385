"""Every clip's figure stays inside the frame for its whole length, catch and anchor clips
included, at the set's one scale; shadows are smooth (:meth:`rendering.Framing.shot`).

Three clips left the frame under the rule's follow camera alone (rendering VERSION 7):
a generated-like walk that side-steps 2.4 m in a sixth of a second (the camera, smoothed
over a second, lagged: out by the right edge), a catch clip whose body floats up off
the floor (out of the top) and a low anchor (joints shaken by 12 % of the figure's size:
out of the top and bottom).
"""

import numpy as np
import pytest

from rendering import Framing, get_style
from rendering.backdrop import Backdrop
from rendering.measure import bare_style, figure_rows
from tests.rendering.conftest import drifting_walk, make_figure, rising_figure, shaken_anchor
from tests.rendering.helpers import figure_box

SIZE = 96
FRAMES = 50
FPS = 25.0


@pytest.fixture(scope="module")
def clip_set():
    real = make_figure(frames=FRAMES, speed=1.2, fps=FPS)
    moved = {"drifting walk": drifting_walk(), "rising catch": rising_figure(),
             "anchor": shaken_anchor()}
    return real, moved, Framing.from_motions([real, *moved.values()])


def _inside(box, size=SIZE) -> bool:
    """No part of the figure on the frame's outermost rows or columns (nothing cut)."""
    return box is not None and box[0] >= 1 and box[1] >= 1 and box[2] <= size - 2 \
        and box[3] <= size - 2


def test_these_clips_left_the_frame_under_the_follow_camera_alone(clip_set):
    _, moved, framing = clip_set
    reach = get_style("stick")(framing, SIZE, SIZE).reach("h36m17")
    for name, motion in moved.items():
        placed = framing.place(motion)
        low, high = framing._boxes(placed, framing.targets(motion, placed), SIZE, SIZE, reach)
        out = ((low < 0) | (high > SIZE)).any(axis=1)
        assert out.any(), f"{name}: stays inside without the shot; the test shows nothing"


def test_the_figure_stays_inside_on_every_frame(clip_set):
    real, moved, framing = clip_set
    with get_style("stick")(framing, SIZE, SIZE) as drawer:
        for name, motion in {"real walk": real, **moved}.items():
            frames = list(drawer.frames(motion))
            assert len(frames) == FRAMES and frames[0].shape == (SIZE, SIZE, 3)
            outside = [n for n, frame in enumerate(frames) if not _inside(figure_box(frame))]
            assert not outside, f"{name}: the figure reaches the frame's edge on {outside}"


def test_the_set_keeps_its_scale(clip_set):
    """Only a body flung apart on some frame may be filmed from farther away; a clip that
    fits the rule as it is gets the rule's frames unchanged."""
    real, moved, framing = clip_set
    drawer = get_style("stick")(framing, SIZE, SIZE)
    shots = {name: framing.shot(m, SIZE, SIZE, drawer.reach(m.skeleton))
             for name, m in {"real walk": real, **moved}.items()}
    assert shots["real walk"].margin == (0, 0) and not shots["real walk"].offsets.any()
    assert np.array_equal(shots["real walk"].targets, framing.targets(real, framing.place(real)))
    for name in ("real walk", "drifting walk", "rising catch"):
        assert shots[name].framing == framing, name
    assert shots["drifting walk"].offsets[:, 0].max() > 0  # the window went right
    assert shots["rising catch"].offsets[:, 1].min() < 0  # and up
    # The window moves smoothly: never faster than the figure's box (as the rule films
    # it) moves from frame to frame, give or take a pixel.
    for name, motion in {"real walk": real, **moved}.items():
        shot = shots[name]
        low, high = shot.framing._boxes(framing.place(motion), shot.targets, SIZE, SIZE,
                                        drawer.reach(motion.skeleton))
        figure = np.maximum(np.abs(np.diff(low, axis=0)), np.abs(np.diff(high, axis=0)))
        window = np.abs(np.diff(shot.offsets, axis=0))
        assert (window <= figure + 1.5).all(), f"{name}: the window jumps"


def test_a_mesh_figure_stays_inside_too(clip_set):
    """The mesh style (its own pad: an SMPL-like body around the joints) on every 4th
    frame; the figure is told from the bare backdrop, the shadow left out."""
    _, moved, framing = clip_set
    size = 64
    style = bare_style("mesh")
    with style(framing, size, size) as drawer:
        for name, motion in moved.items():
            shot = framing.shot(motion, size, size, drawer.reach(motion.skeleton))
            backdrop = Backdrop(shot.framing, size, size, shot.margin)
            for number, frame in enumerate(drawer.frames(motion)):
                if number % 4:
                    continue
                scenery = shot.cut(backdrop.image(shot.targets[number]), number, size, size)
                rows = figure_rows(frame, scenery)
                columns = figure_rows(frame.transpose(1, 0, 2), scenery.transpose(1, 0, 2))
                assert rows and columns, f"{name}: no figure on frame {number}"
                assert rows[0] >= 1 and rows[1] <= size - 2, f"{name} {number}: rows {rows}"
                assert columns[0] >= 1 and columns[1] <= size - 2, \
                    f"{name} {number}: columns {columns}"


def test_shadows_are_smooth(clip_set):
    """The shadow's map changes by at most a quarter of its darkest from one pixel to the
    next (drawn aliased and barely blurred it stepped by 0.4 in 2x2 blocks at this size),
    and is never cut inside the frame."""
    real, moved, framing = clip_set
    masks = []

    class Recorded(get_style("stick")):
        def _shadow(self, plan, number):
            shadow = super()._shadow(plan, number)
            if shadow is not None:
                masks.append(shadow)
            return shadow

    with Recorded(framing, SIZE, SIZE) as drawer:
        for motion in [real, *moved.values()]:
            shot = framing.shot(motion, SIZE, SIZE, drawer.reach(motion.skeleton))
            canvas = shot.canvas(SIZE, SIZE)
            masks.clear()
            for _ in drawer.frames(motion):
                pass
            assert masks
            for mask, (left, top) in masks:
                mask = mask.astype(int)
                peak = max(mask.max(), 1)
                step = max(np.abs(np.diff(mask, axis=0)).max(), np.abs(np.diff(mask, axis=1)).max())
                assert step <= 0.3 * peak, f"{motion.source}: a step of {step / peak:.2f}"
                inner = []  # the map's sides that are not the canvas's edges
                if top > 0:
                    inner.append(mask[0])
                if left > 0:
                    inner.append(mask[:, 0])
                if top + mask.shape[0] < canvas[1]:
                    inner.append(mask[-1])
                if left + mask.shape[1] < canvas[0]:
                    inner.append(mask[:, -1])
                assert max((side.max() for side in inner), default=0) <= 0.05 * peak


def test_the_shot_reads_the_content_never_the_source(clip_set):
    """The same motion labelled real, generated, catch or anchor is filmed alike."""
    _, moved, framing = clip_set
    reach = get_style("stick")(framing, SIZE, SIZE).reach("h36m17")
    for motion in moved.values():
        shots = [framing.shot(motion.with_joints(motion.joints, source=source), SIZE, SIZE,
                              reach) for source in ("real", "cond_gru", "broken", "anchor")]
        for shot in shots[1:]:
            assert shot.framing == shots[0].framing and shot.margin == shots[0].margin
            assert np.array_equal(shot.offsets, shots[0].offsets)


def test_a_still_camera_follows_a_figure_that_outgrows_the_frame():
    """A walker coming up to a still camera is followed (at the set's scale); one that
    stays in view keeps the camera still."""
    towards = make_figure(frames=60, speed=2.5, fps=FPS)  # 6 m, passing near the eye
    standing = make_figure(frames=60, speed=0.0, fps=FPS)
    framing = Framing.from_motions([standing], follow=False)
    reach = get_style("stick")(framing, SIZE, SIZE).reach("h36m17")
    still = framing.shot(standing, SIZE, SIZE, reach)
    assert still.framing == framing and not still.offsets.any()
    shot = framing.shot(towards, SIZE, SIZE, reach)
    placed = framing.place(towards)
    low, high = shot.framing._boxes(placed, shot.targets, SIZE, SIZE, reach)
    low, high = low - shot.offsets, high - shot.offsets
    assert (low >= 0).all() and (high <= SIZE).all()
    assert shot.framing.follow and shot.framing.distance == framing.distance
    low, high = framing._boxes(placed, framing.targets(towards, placed), SIZE, SIZE, reach)
    assert ((high - low) > SIZE).any()  # it did outgrow the still camera's frame


def test_the_sidecar_tells_the_researcher_how_each_clip_was_filmed(tmp_path):
    import json

    from rendering import render_set

    real = make_figure(frames=20, speed=1.2, fps=FPS)
    rising = rising_figure(frames=20, fps=FPS, at=0.2)
    report = render_set([real, rising], tmp_path, size=64, progress=False)
    clips = json.loads(report.sidecar.read_text())["clips"]
    shots = {clip["source"]: clip["shot"] for clip in clips}
    assert shots["real"] == {"zoom": 1.0, "window": [0, 0], "follows": False}
    assert shots["broken"]["window"][1] > 0 and not shots["broken"]["follows"]
