"""WebM and GIF beside the mp4, grid videos with contact sheets, and memory that stays flat."""

import json
import tracemalloc

import numpy as np
import pytest
from django.core.management import CommandError, call_command
from PIL import Image

from motion.formats import npz
from rendering import Framing, get_style, render_grid, render_set
from rendering.grid import GAP
from tests.conftest import make_motion
from tests.rendering.conftest import make_figure
from tests.rendering.helpers import decode

SIZE = 96


@pytest.fixture(scope="module")
def every_format(tmp_path_factory):
    out = tmp_path_factory.mktemp("formats")
    motions = [make_figure(frames=6, speed=1.0)]
    return out, render_set(motions, out, size=SIZE, progress=False,
                           formats=("mp4", "webm", "gif"))


def test_webm_and_gif_sit_beside_the_mp4_and_decode(every_format):
    out, report = every_format
    clip = report.clips[0]
    assert set(clip.extras) == {"webm", "gif"}
    _, mp4 = decode(clip.video)
    for kind, codec in (("webm", "vp9"), ("gif", "gif")):
        path = clip.extras[kind]
        assert path == out / f"{clip.video_hash}.{kind}"
        meta, frames = decode(path)
        assert meta["codec"].startswith(codec) and frames.shape == (6, SIZE, SIZE, 3)
        assert np.abs(frames.astype(int) - mp4).mean() < 6, f"the {kind} shows another picture"
    record = json.loads((out / "renders.json").read_text())
    assert record["formats"] == ["mp4", "webm", "gif"]
    assert record["clips"][0]["extras"] == {"webm": f"{clip.video_hash}.webm",
                                            "gif": f"{clip.video_hash}.gif"}
    assert not list(out.glob(".rendering-*")), "temporary files were left behind"


def test_extra_formats_are_byte_identical_for_the_same_input(every_format, tmp_path):
    _, report = every_format
    again = render_set([make_figure(frames=6, speed=1.0)], tmp_path, size=SIZE, progress=False,
                       formats=("mp4", "webm", "gif"), framing=report.framing)
    for kind in ("webm", "gif"):
        assert again.clips[0].extras[kind].read_bytes() == report.clips[0].extras[kind].read_bytes()
    assert b"encoder" not in report.clips[0].extras["webm"].read_bytes().lower()


def test_formats_are_checked(tmp_path):
    with pytest.raises(ValueError, match="include 'mp4'"):
        render_set([make_figure(frames=2)], tmp_path, formats=("gif",), progress=False)
    with pytest.raises(ValueError, match="unknown video formats"):
        render_set([make_figure(frames=2)], tmp_path, formats=("mp4", "avi"), progress=False)


def test_grid_writes_a_labelled_video_and_a_contact_sheet(tmp_path):
    motions = [make_figure(frames=n, phase=n) for n in (6, 4, 6)]
    grid = render_grid(motions, ["real", "a2m", "cond_gru"], tmp_path / "grid.mp4", size=64,
                       moments=3)
    band = grid.size[1] - 2 * 64 - GAP
    band //= 2
    meta, frames = decode(grid.video)
    assert frames.shape == (6, 2 * 64 + 2 * band + GAP, 2 * 64 + GAP, 3)
    assert grid.size == (frames.shape[2], frames.shape[1]) and meta["codec"] == "h264"
    label = frames[0, :band, :64].astype(int)
    assert (label.sum(axis=-1) < 400).sum() > 10, "no label text drawn"
    held = np.s_[band:band + 64, 64 + GAP:]  # the second clip is over: its cell holds still
    assert np.abs(frames[-1][held].astype(int) - frames[-2][held]).mean() < 1
    assert np.abs(frames[-1][held].astype(int) - frames[1][held]).mean() > 1
    sheet = Image.open(grid.sheet)
    assert grid.sheet == tmp_path / "grid.png"
    assert sheet.size == (3 * 64 + 2 * GAP, 3 * (64 + band) + 2 * GAP)


def test_grid_refuses_what_it_cannot_draw(tmp_path):
    with pytest.raises(ValueError, match="2 labels for 1 motions"):
        render_grid([make_figure(frames=2)], ["a", "b"], tmp_path / "g.mp4")
    with pytest.raises(ValueError, match="motion 1"):
        render_grid([make_figure(frames=2), make_motion(frames=2, skeleton="h36m15_2d")], None,
                    tmp_path / "g.mp4")


def test_render_command_writes_formats_and_a_grid(tmp_path, capsys):
    clips = npz.save(tmp_path / "m.npz", [make_figure(frames=4), make_figure(frames=4, phase=2)])
    out, grid = tmp_path / "out", tmp_path / "grid.mp4"
    call_command("render", str(clips), "--out", str(out), "--size", "64", "--formats", "webm,gif",
                 "--grid", str(grid), "--grid-size", "48", verbosity=0)
    for kind in ("mp4", "webm", "gif", "png"):
        assert len(list(out.glob(f"*.{kind}"))) == 2, kind
    assert grid.is_file() and grid.with_suffix(".png").is_file()
    assert "grid of 2 clips" in capsys.readouterr().out
    with pytest.raises(CommandError, match="unknown --formats"):
        call_command("render", str(clips), "--out", str(out), "--formats", "avi")
    with pytest.raises(CommandError, match="--out"):
        call_command("render", str(clips))


@pytest.mark.parametrize("style", ["stick", "mesh"])
def test_memory_does_not_grow_with_clip_length(style):
    """Frames stream through: a clip ten times longer needs no more memory."""
    framing = Framing.from_motions([make_figure(frames=2)], pad=get_style(style).pad)
    with get_style(style)(framing, 64, 64) as drawer:
        peaks = []
        for frames in (8, 80):
            motion = make_figure(frames=frames, speed=1.0)
            next(drawer.frames(make_figure(frames=1)))  # caches and GL buffers made first
            tracemalloc.start()
            for _ in drawer.frames(motion):
                pass
            peaks.append(tracemalloc.get_traced_memory()[1])
            tracemalloc.stop()
    assert peaks[1] < peaks[0] + 256 * 1024, peaks


@pytest.mark.parametrize("kind", ["mp4", "webm"])
def test_writing_in_the_callers_thread_gives_the_same_file(tmp_path, kind):
    """background=False encodes in groups in the caller's thread (rendering processes
    sharing the cores): the bytes are those of the writer thread's, for a clip longer
    than one group and not a multiple of it."""
    from rendering.video import BATCH_FRAMES, VideoWriter

    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (32, 32, 3), dtype=np.uint8) for _ in range(BATCH_FRAMES + 5)]
    paths = []
    for background in (True, False):
        path = tmp_path / f"{background}.{kind}"
        with VideoWriter(path, 32, 32, 25, background=background) as writer:
            for frame in frames:
                writer.write(frame)
        paths.append(path)
    assert paths[0].read_bytes() == paths[1].read_bytes()
    assert decode(paths[1])[1].shape == (len(frames), 32, 32, 3)


@pytest.mark.parametrize("width,height", [(96, 96), (96, 98), (98, 64)])
def test_the_mp4_writer_gives_the_bytes_of_ffmpeg_with_the_same_settings(tmp_path, width,
                                                                          height):
    """x264 runs in-process, yet the file is byte for byte what the ffmpeg command line
    writes with encoder_options from the same yuv420p frames: anyone with this project's
    pinned OpenCV (which makes them, rendering.video.to_yuv420p) can reproduce a clip.
    Heights of 2 more than a multiple of 4 included: PyAV's zero-copy frames misread them."""
    import subprocess

    import imageio_ffmpeg

    from rendering.video import VideoWriter, encoder_options, to_yuv420p

    motion = make_figure(frames=12, speed=1.5)
    framing = Framing.from_motions([motion], aspect=width / height, pad=get_style("stick").pad)
    with get_style("stick")(framing, width, height) as drawer:
        frames = list(drawer.frames(motion))
    ours = tmp_path / "ours.mp4"
    with VideoWriter(ours, width, height, 25, pad=False) as writer:
        for frame in frames:
            writer.write(frame)
    theirs = tmp_path / "ffmpeg.mp4"
    subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-f", "rawvideo", "-pix_fmt", "yuv420p",
         "-s", f"{width}x{height}", "-r", "25", "-i", "-", "-c:v", "libx264",
         "-pix_fmt", "yuv420p", *encoder_options("mp4", width, height, 25), str(theirs)],
        input=b"".join(to_yuv420p(frame).tobytes() for frame in frames), check=True)
    assert ours.read_bytes() == theirs.read_bytes()
    # And the clip shows the frames (a misread plane would tint it by tens of levels).
    decoded = decode(ours)[1].astype(int)
    assert np.abs(decoded - np.array(frames, dtype=int)).mean() < 4


def test_chroma_is_the_mean_of_each_2x2_block():
    """One red pixel anywhere in a 2x2 block tints that block's chroma by a quarter of
    red's (OpenCV's own I420 conversion would see it only at the block's top left)."""
    from rendering.video import to_yuv420p

    tints = []
    for row, column in ((0, 0), (0, 1), (1, 0), (1, 1)):
        frame = np.zeros((4, 4, 3), np.uint8)
        frame[row, column] = (255, 0, 0)
        planes = to_yuv420p(frame).astype(int)
        tints.append((planes[4, 0], planes[5, 0]))  # Cb and Cr of the top-left block
    # BT.601 limited range: red's Cb is 128 - 37.797, Cr 128 + 112; a quarter of each.
    assert all(abs(cb - (128 - 37.797 / 4)) <= 1 and abs(cr - (128 + 112 / 4)) <= 1
               for cb, cr in tints)


def test_frames_convert_to_yuv420p_as_ffmpeg_does_within_its_chroma_filter():
    """Our RGB to yuv420p conversion is ffmpeg's (BT.601, limited range) up to the chroma
    filter: the same luma, chroma within a few levels on flat colour."""
    import av

    from rendering.video import to_yuv420p

    rng = np.random.default_rng(0)
    # Blocks of flat colour, 8 pixels wide, as clips are mostly made of.
    frame = np.kron(rng.integers(0, 256, (6, 6, 3)), np.ones((8, 8, 1))).astype(np.uint8)
    ours = to_yuv420p(frame).astype(int)
    theirs = av.VideoFrame.from_ndarray(frame, format="rgb24").reformat(
        format="yuv420p").to_ndarray().astype(int)
    assert ours.shape == theirs.shape == (72, 48)
    assert np.abs(ours[:48] - theirs[:48]).max() <= 1  # luma
    for plane in (slice(48, 60), slice(60, 72)):  # U and V: 24 x 24 samples, 4 per block
        difference = np.abs(ours[plane] - theirs[plane]).reshape(6, 4, 6, 4)
        assert difference[:, 1:3, :, 1:3].max() <= 2  # inside each block, away from its edges


@pytest.mark.parametrize("background", [True, False])
def test_an_encoder_failing_mid_clip_names_the_file_and_leaves_none(tmp_path, monkeypatch,
                                                                    background):
    from rendering import video

    def broken(self, prepared):
        raise OSError("disk full")

    monkeypatch.setattr(video._X264, "send", broken)
    path = tmp_path / "clip.mp4"
    frame = np.zeros((32, 32, 3), np.uint8)
    with pytest.raises(RuntimeError, match=f"stopped writing {path}.*disk full"):
        with video.VideoWriter(path, 32, 32, 25, background=background) as writer:
            for _ in range(video.BATCH_FRAMES + 2):
                writer.write(frame)
    assert not path.exists()
