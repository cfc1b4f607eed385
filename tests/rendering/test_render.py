"""Render real clips and read them back: frames, size, framing, naming, bytes."""

import numpy as np
import pytest
from PIL import Image

from motion.motion import Motion
from rendering import RenderedClip, render_motion, render_set, resample
from rendering.batch import SIDECAR
from tests.conftest import make_motion
from tests.rendering.conftest import make_figure
from tests.rendering.helpers import decode, figure_box

SIZE = 160
SECRETS = (b"zebracrossing", b"secretmethod", b"lavf", b"lavc", b"x264", b"encoder")


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Render a walking and a swaying figure, with distinctive action and source names."""
    out = tmp_path_factory.mktemp("renders")
    motions = [
        make_figure(frames=12, speed=1.5, action="zebracrossing", source="secretmethod"),
        make_figure(frames=12, phase=1.0, action="zebracrossing", source="real"),
    ]
    return motions, out, render_set(motions, out, size=SIZE, progress=False)


def test_clips_decode_with_their_frames_and_size(rendered):
    motions, _, report = rendered
    assert report.failures == []
    assert [clip.index for clip in report.clips] == [0, 1]
    for clip in report.clips:
        meta, frames = decode(clip.video)
        assert frames.shape == (12, SIZE, SIZE, 3)
        assert (clip.frames, clip.fps, clip.size) == (12, 25.0, (SIZE, SIZE))
        assert clip.duration == pytest.approx(12 / 25)
        assert meta["codec"] == "h264" and meta["pix_fmt"].startswith("yuv420p")
        assert frames.std() > 10, "the video is blank"
        assert Image.open(clip.poster).size == (SIZE, SIZE)


def test_figure_stays_inside_the_frame_in_every_frame(rendered):
    _, _, report = rendered
    margin = 3
    for clip in report.clips:
        _, frames = decode(clip.video)
        for frame in frames:
            box = figure_box(frame)
            assert box is not None, "no figure drawn"
            left, top, right, bottom = box
            assert left >= margin and top >= margin
            assert right < SIZE - margin and bottom < SIZE - margin


@pytest.mark.parametrize("skeleton", ["h36m17", "humanact12"])
def test_left_is_warm_and_right_is_cool_on_screen(skeleton, tmp_path):
    """Figures start facing the viewer: their right side (blue) is on the image's left."""
    clip = render_motion(make_figure(skeleton, frames=1), tmp_path / "side.mp4", size=SIZE)
    frame = np.asarray(Image.open(clip.poster)).astype(int)
    red, blue = frame[..., 0], frame[..., 2]
    warm = np.nonzero((red - blue) > 80)[1]
    cool = np.nonzero((blue - red) > 80)[1]
    assert len(warm) > 20 and len(cool) > 20
    assert cool.mean() < warm.mean()


def test_different_motions_give_different_videos(rendered):
    _, _, report = rendered
    first, second = report.clips
    assert first.video_hash != second.video_hash
    assert first.motion_hash != second.motion_hash


def test_same_input_renders_byte_identical_files(rendered, tmp_path):
    motions, _, report = rendered
    again = render_set(motions[:1], tmp_path, size=SIZE, progress=False, framing=report.framing)
    clip = again.clips[0]
    assert clip.video.read_bytes() == report.clips[0].video.read_bytes()
    assert clip.poster.read_bytes() == report.clips[0].poster.read_bytes()
    assert clip.video.name == report.clips[0].video.name


def test_names_and_bytes_reveal_no_source(rendered):
    _, out, report = rendered
    for clip in report.clips:
        assert clip.video.name == f"{clip.video_hash}.mp4"
        assert clip.poster.name == f"{clip.video_hash}.png"
        assert len(clip.video_hash) == 16 and int(clip.video_hash, 16) >= 0
        for path in (clip.video, clip.poster):
            data = path.read_bytes().lower()
            for secret in SECRETS:
                assert secret not in data, (path.name, secret)
    served = {p.name for p in out.iterdir()} - {SIDECAR}
    assert all("zebra" not in name and "secret" not in name for name in served)


def test_videos_start_with_their_index(rendered):
    """Faststart: the moov atom comes before the media data, so browsers stream it."""
    _, _, report = rendered
    for clip in report.clips:
        data = clip.video.read_bytes()
        assert 0 < data.find(b"moov") < data.find(b"mdat")


def test_sidecar_lists_what_was_rendered(rendered):
    import json

    motions, out, report = rendered
    record = json.loads((out / SIDECAR).read_text())
    assert [c["video"] for c in record["clips"]] == [c.video.name for c in report.clips]
    assert [c["source"] for c in record["clips"]] == ["secretmethod", "real"]
    assert record["clips"][0]["frames"] == 12 and record["framing"]["dims"] == 3


def test_bad_clips_fail_alone(tmp_path):
    good = make_figure(frames=6)
    broken = make_figure(frames=6).joints.copy()
    broken[3, 2] = np.nan
    wrong_shape = make_figure(frames=6)
    object.__setattr__(wrong_shape, "joints", wrong_shape.joints[:, :5])
    empty = Motion(np.zeros((0, 17, 3)), "h36m17", 25.0, "walk")
    flat = make_motion(frames=6, skeleton="h36m15_2d")
    motions = [Motion(broken, "h36m17", 25.0, "walk"), wrong_shape, empty, good, flat]
    report = render_set(motions, tmp_path, size=SIZE, progress=False)
    assert [clip.index for clip in report.clips] == [3]
    messages = dict(report.failures)
    assert sorted(messages) == [0, 1, 2, 4]
    assert "non-finite" in messages[0]
    assert "do not fit skeleton" in messages[1]
    assert "no frames" in messages[2]
    assert "2D" in messages[4]


def test_unwritable_folder_fails_every_clip(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    report = render_set([make_figure(frames=4)] * 2, blocker / "out", size=SIZE, progress=False)
    assert report.clips == []
    assert [index for index, _ in report.failures] == [0, 1]
    assert all("output folder" in message for _, message in report.failures)


def test_resampling_changes_the_frame_rate(tmp_path):
    report = render_set([make_figure(frames=12)], tmp_path, size=SIZE, fps=50, progress=False)
    clip = report.clips[0]
    assert (clip.frames, clip.fps) == (23, 50.0)
    meta, frames = decode(clip.video)
    assert len(frames) == 23 and meta["fps"] == 50.0


def test_resample_interpolates_linearly():
    motion = make_figure(frames=5)
    doubled = resample(motion, 50.0)
    assert doubled.frames == 9
    halfway = (motion.joints[0] + motion.joints[1]) / 2
    np.testing.assert_allclose(doubled.joints[1], halfway, atol=1e-6)
    np.testing.assert_allclose(doubled.joints[::2], motion.joints, atol=1e-6)


def test_render_motion_writes_the_given_path(tmp_path):
    clip = render_motion(make_figure(frames=3), tmp_path / "one.mp4", size=SIZE)
    assert isinstance(clip, RenderedClip)
    assert clip.video == tmp_path / "one.mp4" and clip.poster == tmp_path / "one.png"
    assert decode(clip.video)[1].shape == (3, SIZE, SIZE, 3)


def test_parallel_workers_render_the_same_files(rendered, tmp_path):
    motions, _, report = rendered
    parallel = render_set(motions, tmp_path, size=SIZE, workers=2, progress=False)
    assert [c.video_hash for c in parallel.clips] == [c.video_hash for c in report.clips]


def test_parallel_rendering_shares_the_clips_between_this_process_and_a_worker(tmp_path):
    """workers=2: this process draws from the end while a spawned worker takes the front;
    every clip is rendered once, byte for byte as alone, a bad one fails alone, and
    progress is told once per clip drawn."""
    motions = [make_figure(frames=6, speed=0.5 + 0.25 * k) for k in range(9)]
    joints = motions[4].joints.copy()
    joints[2, 1] = np.nan
    motions[4] = motions[4].with_joints(joints)
    seen = []
    serial = render_set(motions, tmp_path / "serial", size=SIZE, progress=False)
    parallel = render_set(motions, tmp_path / "parallel", size=SIZE, workers=2, progress=False,
                          on_clip=seen.append)
    assert sorted(seen) == [0, 1, 2, 3, 5, 6, 7, 8]  # the clips that could be drawn
    assert [i for i, _ in parallel.failures] == [4] and "non-finite" in parallel.failures[0][1]
    assert [c.index for c in parallel.clips] == [0, 1, 2, 3, 5, 6, 7, 8]
    assert [c.video_hash for c in parallel.clips] == [c.video_hash for c in serial.clips]
    files = sorted(p.name for p in (tmp_path / "parallel").iterdir())
    assert len(files) == 2 * 8 + 1  # an mp4 and a poster per clip, the sidecar


def test_an_error_while_rendering_in_parallel_stops_without_waiting_for_the_rest(tmp_path):
    """The calling process's own failure (here its progress callback) is raised at once:
    the clips not yet handed to a worker are never started."""
    motions = [make_figure(frames=6, speed=0.5 + 0.1 * k) for k in range(12)]

    def stop(index):
        raise RuntimeError(f"stopped at clip {index}")

    with pytest.raises(RuntimeError, match="stopped at clip"):
        render_set(motions, tmp_path, size=SIZE, workers=2, progress=False, on_clip=stop)
    assert len(list(tmp_path.glob("*.mp4"))) < len(motions)


def test_following_camera_keeps_a_fast_walker_inside(tmp_path):
    walker = make_figure(frames=12, speed=4.0)
    report = render_set([walker], tmp_path, size=SIZE, follow=True, progress=False)
    assert report.framing.follow
    _, frames = decode(report.clips[0].video)
    for frame in frames:
        left, top, right, bottom = figure_box(frame)
        assert left > 0 and top > 0 and right < SIZE - 1 and bottom < SIZE - 1
