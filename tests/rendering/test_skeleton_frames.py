"""The new skeletons in every style: upright, feet on the ground, facing the camera, in metres;
and the mesh style drawing a body surface that came with the motion."""

import numpy as np
import pytest
from PIL import Image

from motion import ops
from motion.formats import bvh
from motion.motion import Motion
from motion.skeletons import get_skeleton
from rendering import get_style, render_set
from rendering.backdrop import Backdrop
from rendering.palette import LEFT, RIGHT
from tests.rendering.helpers import decode

SIZE = 128
# A standing person: (towards their left, up, forward), metres.
PARTS = {
    "pelvis": (0, .95, 0), "spine1": (0, 1.05, 0), "spine2": (0, 1.18, 0), "spine3": (0, 1.3, 0),
    "root": (0, .95, 0), "spine": (0, 1.1, 0), "chest": (0, 1.3, 0), "neck": (0, 1.48, .01),
    "head": (0, 1.6, .03), "hip": (.1, .92, 0), "knee": (.11, .5, .02), "ankle": (.11, .08, -.02),
    "foot": (.12, .02, .12), "toe": (.12, .01, .18), "collar": (.06, 1.42, 0),
    "shoulder": (.18, 1.42, 0), "elbow": (.21, 1.15, -.02), "wrist": (.23, .9, .02),
    "hand": (.23, .82, .03),
}


def standing(skeleton: str, frames: int = 2) -> Motion:
    """Return a person standing still in the skeleton's own axes and units."""
    pose = []
    for name in get_skeleton(skeleton).joint_names:
        side, _, part = name.partition("_")
        left, up, forward = PARTS[part] if side in ("left", "right") else PARTS[name]
        pose.append((-left if side == "right" else left, up, forward))
    left, up, forward = np.array(pose).T
    if skeleton == "kit21":  # KIT-ML: the right side along +x, millimetres
        joints = np.stack([-left, up, -forward], axis=-1) * 1000.0
    else:  # SMPL: the left side along +x, metres
        joints = np.stack([left, up, forward], axis=-1)
    return Motion(np.repeat(joints[None], frames, axis=0), skeleton, 20.0, "stand")


def _near(frame: np.ndarray, colour, tolerance=60) -> np.ndarray:
    return np.abs(frame.astype(int) - colour).max(axis=-1) < tolerance


def _ground_line(report, motion, style) -> float:
    """Return the image row where the figure's lowest joint touches the floor."""
    canonical = ops.canonical(motion, get_style(style).dims)
    placed = report.framing.place(canonical)[0]
    camera = report.framing.camera(SIZE, SIZE)
    lowest = placed[np.argmin(placed[:, 2])] * [1, 1, 0]
    return float(camera.project(lowest)[0][1])


@pytest.fixture(scope="module", params=["stick", "stick2d", "mesh"])
def rendered(request, tmp_path_factory):
    style = request.param
    out = tmp_path_factory.mktemp(style)
    motions = [standing(name) for name in ("smpl22", "smpl24", "kit21")]
    report = render_set(motions, out, style=style, size=SIZE, progress=False)
    assert report.failures == []
    return style, motions, report


def test_new_skeletons_stand_on_the_ground_upright(rendered):
    style, motions, report = rendered
    heights = []
    for motion, clip in zip(motions, report.clips):
        _, frames = decode(clip.video)
        frame = frames[0]
        scenery = Backdrop(report.framing, SIZE, SIZE).image().astype(int)
        # The figure, and the darkest of its shadow where it touches the floor.
        figure = np.abs(frame.astype(int) - scenery).max(axis=-1) > 60
        ys, _ = np.nonzero(figure)
        top, bottom = ys.min(), ys.max()
        ground = _ground_line(report, motion, style)
        assert abs(bottom - ground) < 0.06 * SIZE, f"{motion.skeleton}: feet off the ground line"
        heights.append(bottom - top)
        if style != "mesh":
            # Upright: the top rows are the neutral head, the coloured feet reach the floor.
            coloured = _near(frame, LEFT) | _near(frame, RIGHT)
            assert not coloured[top:top + 3].any(), f"{motion.skeleton}: limbs above the head"
            assert np.nonzero(coloured)[0].max() >= ground - 0.04 * SIZE, motion.skeleton
        else:
            # Upright: the widest rows (shoulders and arms) are in the upper half of the body.
            rows = figure[top:bottom - int(0.2 * (bottom - top))].sum(axis=1)
            assert np.argmax(rows) < 0.5 * (bottom - top), motion.skeleton
    # One body in metres and in millimetres is drawn the same size.
    assert max(heights) - min(heights) <= 0.06 * max(heights), heights


def test_new_skeletons_face_the_camera(rendered):
    style, motions, report = rendered
    if style == "mesh":
        pytest.skip("the mesh's sides differ by a faint tint only")
    for motion, clip in zip(motions, report.clips):
        frame = np.asarray(Image.open(clip.poster))
        left = np.nonzero(_near(frame, LEFT))[1].mean()
        right = np.nonzero(_near(frame, RIGHT))[1].mean()
        assert left > right, f"{motion.skeleton}: its left side must show on the image's right"


def _box(low, high):
    """Return the 8 vertices and 12 triangles of a box."""
    vertices = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                         for z in (low[2], high[2])], dtype=float)
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7],
             [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    return vertices, np.array(faces)


def test_mesh_draws_the_body_surface_the_motion_carries(tmp_path):
    motion = standing("smpl22")
    vertices, faces = _box((-0.5, -0.06, -0.1), (0.5, 1.7, 0.1))  # a broad slab, y up
    slab = motion.with_joints(motion.joints, vertices=np.repeat(vertices[None], 2, axis=0),
                              faces=faces)
    report = render_set([motion, slab], tmp_path, style="mesh", size=SIZE, progress=False)
    assert report.failures == []
    scenery = Backdrop(report.framing, SIZE, SIZE).image().astype(int)
    widths = []
    for clip in report.clips:
        frame = decode(clip.video)[1][0].astype(int)
        changed = np.abs(frame - scenery).max(axis=-1) > 30
        ys, xs = np.nonzero(changed)
        middle = changed[(ys.min() + ys.max()) // 2]
        widths.append(middle.sum())
    assert widths[1] > 2 * widths[0], "the slab, 1 m wide, not the synthetic body, was drawn"
    assert report.clips[0].motion_hash != report.clips[1].motion_hash


def test_a_bvh_hierarchy_renders_as_its_own_skeleton(tmp_path):
    from tests.motion.test_formats import FIXTURE

    [motion] = bvh.load(FIXTURE)
    for style in ("stick", "mesh"):
        report = render_set([motion], tmp_path / style, style=style, size=96, progress=False)
        assert report.failures == [], report.failures
        frames = decode(report.clips[0].video)[1]
        assert frames.std() > 5
