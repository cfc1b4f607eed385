"""Files that tell nothing about their content: one size, one layout, no metadata.

A still figure and a wildly jittered one of the same length are the extremes of what a
study shows (a frozen generated clip, a broken catch clip); everything a participant can
read off their files without decoding a frame must be the same.
"""

import io

import numpy as np
import pytest
from PIL import Image

from rendering import render_set
from rendering import batch, video
from rendering.padding import PaddingError, mp4_boxes, pad
from tests.rendering.conftest import make_figure
from tests.rendering.helpers import decode

SIZE = 96
FRAMES = 20
FORMATS = ("mp4", "webm", "gif")


def _extremes():
    walker = make_figure(frames=FRAMES, speed=1.5)
    still = walker.with_joints(np.repeat(walker.joints[:1], FRAMES, axis=0), source="a2m")
    rng = np.random.default_rng(3)
    jitter = rng.normal(scale=0.3, size=walker.joints.shape)
    broken = walker.with_joints((walker.joints + jitter).astype(np.float32), source="broken")
    return [walker, still, broken]


@pytest.fixture(scope="module")
def extremes(tmp_path_factory):
    out = tmp_path_factory.mktemp("blind")
    report = render_set(_extremes(), out, size=SIZE, progress=False, formats=FORMATS)
    assert report.failures == []
    return report


def _files(clip):
    return {"mp4": clip.video, "png": clip.poster, **clip.extras}


def test_every_file_has_one_size_per_length_and_resolution(extremes):
    sizes = [{kind: path.stat().st_size for kind, path in _files(c).items()}
             for c in extremes.clips]
    assert sizes[0] == sizes[1] == sizes[2]
    expected = {kind: video.budget(kind, SIZE, SIZE, FRAMES, 25.0) for kind in FORMATS + ("png",)}
    assert sizes[0] == expected
    assert len({c.video_hash for c in extremes.clips}) == 3, "the clips should differ"


def test_mp4_layout_and_metadata_are_the_same_for_every_content(extremes):
    layouts, movies = [], []
    for clip in extremes.clips:
        data = clip.video.read_bytes()
        boxes = mp4_boxes(data)
        kinds = [kind for kind, _, _ in boxes]
        assert kinds[:2] == ["ftyp", "moov"] and kinds[-1] == "free", kinds  # faststart, padded
        layouts.append([(kind, size) for kind, _, size in boxes if kind not in ("mdat", "free")])
        (_, at, size), = [b for b in boxes if b[0] == "moov"]
        movies.append(data[at:at + size])
        for secret in (b"lavf", b"lavc", b"x264", b"encoder", b"broken", b"a2m"):
            assert secret not in data.lower()
    assert layouts[0] == layouts[1] == layouts[2]
    # Every frame is padded to its fixed budget, so even the frame-size table and the
    # chunk offsets are the same: the movie boxes are identical byte for byte.
    assert movies[0] == movies[1] == movies[2]


def test_padded_files_still_decode_with_their_frames(extremes):
    for clip in extremes.clips:
        for kind, path in _files(clip).items():
            if kind == "png":
                image = Image.open(path)
                image.load()
                assert image.size == (SIZE, SIZE)
                continue
            meta, frames = decode(path)
            assert frames.shape == (FRAMES, SIZE, SIZE, 3), kind
            assert meta["duration"] == pytest.approx(FRAMES / 25, abs=0.05), kind
            assert frames.std() > 5, kind


def test_a_clip_over_its_budget_is_encoded_again_with_nothing_that_tells(tmp_path, monkeypatch):
    """With frame budgets at the mean rate the jittered clip's frames overshoot; it is
    encoded again, quantised more coarsely, and its stream parameters stay the same."""
    monkeypatch.setattr(video, "FRAME_HEADROOM", 1.0)
    monkeypatch.setattr(batch, "RATE_SCALES", (1.0, 0.2))
    scales = []
    encode_at = batch._encode_at
    monkeypatch.setattr(batch, "_encode_at",
                        lambda *args: scales.append(args[4]) or encode_at(*args))
    report = render_set(_extremes()[2:], tmp_path, size=SIZE, progress=False)
    assert scales == [1.0, 0.2]
    assert report.failures == []
    clip = report.clips[0]
    assert clip.video.stat().st_size == video.budget("mp4", SIZE, SIZE, FRAMES, 25.0)
    assert decode(clip.video)[1].shape == (FRAMES, SIZE, SIZE, 3)
    still = render_set(_extremes()[:1], tmp_path / "still", size=SIZE, progress=False)

    def avcc(path):  # the stream's parameters (SPS and PPS) as stored in the mp4
        data = path.read_bytes()
        at = data.find(b"avcC")
        return data[at:at - 4 + int.from_bytes(data[at - 4:at], "big")]

    assert avcc(clip.video) == avcc(still.clips[0].video)


def test_padding_refuses_a_file_already_too_large(tmp_path):
    path = tmp_path / "big.mp4"
    path.write_bytes(bytes(100))
    with pytest.raises(PaddingError, match="big.mp4 is 100 bytes"):
        pad(path, 50)
    with pytest.raises(PaddingError, match="cannot be padded to 104"):
        pad(path, 104)  # no room for a box header
    with pytest.raises(PaddingError, match="not one of"):
        pad(tmp_path / "clip.avi", 10)


def test_posters_have_one_png_header_whatever_they_show(tmp_path):
    """A frame too busy for its poster budget is reduced to 256 colours but stays an RGB
    PNG: the header (colour type, bit depth) is the same for every poster."""
    rng = np.random.default_rng(0)
    plain = np.full((64, 64, 3), 200, np.uint8)
    rows, columns = np.mgrid[:64, :64]
    # A gradient with noise: too many colours for the budget as it is, not with 256.
    busy = np.stack([columns * 4, rows * 4, (rows + columns) * 2], axis=-1)
    busy = np.clip(busy + rng.integers(-6, 7, busy.shape), 0, 255).astype(np.uint8)
    headers = []
    for name, frame in (("plain", plain), ("busy", busy)):
        path = video.save_poster(tmp_path / f"{name}.png", frame)
        data = path.read_bytes()
        headers.append(data[:33])  # signature and IHDR: size, bit depth, colour type
        assert path.stat().st_size == video.budget("png", 64, 64, 1, 1)
    encoded = io.BytesIO()
    Image.fromarray(busy).save(encoded, format="PNG", compress_level=3)
    assert encoded.tell() > video.budget("png", 64, 64, 1, 1)  # the busy one was reduced
    assert headers[0] == headers[1]
    assert Image.open(tmp_path / "busy.png").mode == "RGB"
