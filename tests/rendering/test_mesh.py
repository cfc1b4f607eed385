"""The mesh style: a closed body around the skeleton, drawn offscreen, framed like sticks."""

import numpy as np
import pytest
from PIL import Image

from motion.skeletons import Skeleton, get_skeleton
from rendering import Framing, get_style, render_motion, render_set
from rendering.backdrop import Backdrop
from rendering.body import Body
from rendering.measure import bare_style
from rendering.styles.mesh import body_colours
from tests.conftest import make_motion
from tests.rendering.conftest import make_figure
from tests.rendering.helpers import decode

SIZE = 128
FRAMES = 8
# Body parts that meet, and so must overlap: no gap may open at the joint between them.
JUNCTIONS = [("trunk", "neck"), ("neck", "head")] + [
    pair
    for side in ("left", "right")
    for pair in (("trunk", f"{side}_leg"), (f"{side}_leg", f"{side}_foot"),
                 ("trunk", f"{side}_arm"), (f"{side}_arm", f"{side}_hand"))
]


def _changed(frame: np.ndarray, framing: Framing, target=None) -> np.ndarray:
    """Return where a frame differs from the bare scenery: the body and its shadow."""
    scenery = Backdrop(framing, frame.shape[1], frame.shape[0]).image(target).astype(int)
    return np.abs(frame.astype(int) - scenery).max(axis=-1) > 30


def _winding(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Return the winding number of a closed mesh around each point (1 inside, 0 outside)."""
    a, b, c = (vertices[faces[:, k]][None] - points[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    volume = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    spread = (la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc
              + np.einsum("pfi,pfi->pf", b, c) * la + np.einsum("pfi,pfi->pf", c, a) * lb)
    return 2 * np.arctan2(volume, spread).sum(axis=1) / (4 * np.pi)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    out = tmp_path_factory.mktemp("mesh")
    motions = [make_figure(frames=FRAMES, speed=1.5), make_figure(frames=FRAMES, phase=1.0)]
    return motions, render_set(motions, out, style="mesh", size=SIZE, progress=False)


def test_mesh_clips_decode_with_their_frames_and_size(rendered):
    _, report = rendered
    assert report.failures == []
    for clip in report.clips:
        meta, frames = decode(clip.video)
        assert frames.shape == (FRAMES, SIZE, SIZE, 3) and meta["codec"] == "h264"
        assert frames.std() > 10, "the video is blank"
        assert Image.open(clip.poster).size == (SIZE, SIZE)


def test_body_stays_inside_the_frame(rendered):
    """The body, drawn without its floor shadow (which may fall out of the bottom edge)."""
    motions, report = rendered
    framing = report.framing
    with bare_style("mesh")(framing, SIZE, SIZE) as drawer:
        for motion in motions:
            targets = framing.targets(motion, framing.place(motion))
            for frame, target in zip(drawer.frames(motion), targets):
                ys, xs = np.nonzero(_changed(frame, framing, target))
                assert len(xs) > 200, "no body drawn"
                assert xs.min() >= 2 and ys.min() >= 2
                assert xs.max() < SIZE - 2 and ys.max() < SIZE - 2


def test_different_motions_differ_and_the_same_renders_identically(rendered, tmp_path):
    motions, report = rendered
    first, second = report.clips
    assert first.video_hash != second.video_hash
    again = render_set(motions[:1], tmp_path, style="mesh", size=SIZE, progress=False,
                       framing=report.framing)
    assert again.clips[0].video.read_bytes() == first.video.read_bytes()
    assert again.clips[0].poster.read_bytes() == first.poster.read_bytes()


@pytest.mark.parametrize("skeleton", ["h36m17", "humanact12"])
def test_every_3d_skeleton_gets_a_body_with_readable_sides(skeleton, tmp_path):
    """Facing the viewer, the figure's right (cooler) limbs are on the image's left."""
    clip = render_motion(make_figure(skeleton, frames=2), tmp_path / "one.mp4", style="mesh",
                         size=SIZE)
    frame = np.asarray(Image.open(clip.poster)).astype(int)
    framing = Framing.from_motions([make_figure(skeleton, frames=2)], pad=get_style("mesh").pad)
    body = _changed(frame.astype(np.uint8), framing)
    warmth = frame[..., 0] - frame[..., 2]
    warm = np.nonzero(body & (warmth > 5))[1]
    cool = np.nonzero(body & (warmth < -20))[1]
    assert len(warm) > 50 and len(cool) > 50
    assert cool.mean() < warm.mean()


def test_left_limbs_are_warmer_than_right_ones_and_the_rest_neutral():
    left, right, centre = body_colours(np.array(["left", "right", "centre"]))
    assert left[0] - left[2] > centre[0] - centre[2] > right[0] - right[2]
    assert np.ptp(centre[:3]) < 0.1 and (left[3], right[3], centre[3]) == (1.0, 1.0, 1.0)


def test_a_2d_motion_fails_alone_with_a_clear_message(tmp_path):
    motions = [make_figure(frames=4), make_motion(frames=4, skeleton="h36m15_2d")]
    report = render_set(motions, tmp_path, style="mesh", size=64, progress=False)
    assert [clip.index for clip in report.clips] == [0]
    (index, message), = report.failures
    assert index == 1 and "mesh" in message and "2D" in message
    flat = make_motion(frames=2, skeleton="h36m15_2d")
    with get_style("mesh")(Framing.from_motions([flat]), 32, 32) as drawer:
        with pytest.raises(ValueError, match="3D skeletons"):
            next(drawer.frames(flat))


@pytest.mark.parametrize("skeleton", ["h36m17", "humanact12"])
def test_body_pieces_are_closed_and_overlap_where_they_meet(skeleton):
    import trimesh

    motion = make_figure(skeleton, frames=12, speed=1.0)
    placed = Framing.from_motions([motion]).place(motion)
    body = Body(get_skeleton(skeleton), placed)
    pieces = {name: body.tubes.piece(k) for k, name in enumerate(body.pieces)}
    assert set(pieces) == {name for pair in JUNCTIONS for name in pair}
    for pose in placed[::4]:
        vertices = body.pose(pose)[0]
        for name, (indices, faces) in pieces.items():
            mesh = trimesh.Trimesh(vertices, faces, process=False)
            mesh.remove_unreferenced_vertices()
            assert mesh.is_watertight and mesh.is_winding_consistent, name
            assert mesh.volume > 0, f"{name} is inside out"
        for first, second in JUNCTIONS:
            (ia, fa), (ib, fb) = pieces[first], pieces[second]
            inside = max(_winding(vertices[ia], vertices, fb).max(),
                         _winding(vertices[ib], vertices, fa).max())
            assert inside > 0.5, f"{first} and {second} do not overlap: a crack would show"


def test_skeletons_without_a_body_layout_get_closed_bone_tubes():
    h36m = get_skeleton("h36m17")
    other = Skeleton("bones_only", h36m.joint_names, h36m.parents, h36m.left, h36m.right,
                     "z", 3, h36m.chains)
    joints = make_figure(frames=3).joints
    body = Body(other, joints)
    assert len(body.pieces) == len(other.bones)
    vertices, normals = body.pose(joints[0])[:2]
    assert np.isfinite(vertices).all() and np.allclose(np.linalg.norm(normals, axis=1), 1)


def test_two_mesh_styles_live_side_by_side():
    """Closing one must not pull the GL context from under the other."""
    motion = make_figure(frames=2)
    framing = Framing.from_motions([motion])
    first, second = (get_style("mesh")(framing, 32, 32) for _ in range(2))
    before = list(second.frames(motion))
    list(first.frames(make_figure("humanact12", frames=2)))
    first.close()
    after = list(second.frames(motion))
    second.close()
    assert all((a == b).all() for a, b in zip(before, after))


def test_following_camera_keeps_a_fast_walker_inside(tmp_path):
    report = render_set([make_figure(frames=8, speed=4.0)], tmp_path, style="mesh", size=64,
                        follow=True, progress=False)
    framing = report.framing
    for number, frame in enumerate(decode(report.clips[0].video)[1]):
        motion = make_figure(frames=8, speed=4.0)
        target = framing.targets(motion, framing.place(motion))[number]
        scenery = Backdrop(framing, 64, 64).image(target).astype(int)
        ys, xs = np.nonzero(np.abs(frame.astype(int) - scenery).max(axis=-1) > 30)
        assert len(xs) > 30 and xs.min() > 0 and xs.max() < 63 and ys.min() > 0
