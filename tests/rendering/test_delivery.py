"""Per-delivery bytes: every delivery of a clip's files has bytes of its own, of the same
size, with the same frames, tables and pictures, and the same seed gives the same bytes."""

import hashlib
import io
import struct
import zlib

import av
import numpy as np
import pytest
from PIL import Image

from rendering import Framing, render_set
from rendering.delivery import MAX_FILL_CHUNKS, MAX_FILLERS, deliver
from rendering.video import FILLER_ROOM
from rendering.padding import mp4_boxes, nal_units, sample_table
from rendering.player import payload, read
from tests.rendering.conftest import make_figure

FRAMES = 20
SEEDS = [bytes([k]) * 32 for k in range(6)]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A walking and a jittered clip as the build renders them (padded), and payloads."""
    walker = make_figure(frames=FRAMES, speed=1.5)
    rng = np.random.default_rng(3)
    broken = walker.with_joints((walker.joints + rng.normal(scale=0.3, size=walker.joints.shape))
                                .astype(np.float32), source="broken")
    report = render_set([walker, broken], tmp_path_factory.mktemp("delivery"), size=96,
                        progress=False)
    framing = Framing.from_motions([walker, broken])
    return report.clips, [payload(m, framing) for m in (walker, broken)]


def frames_of(data: bytes) -> np.ndarray:
    with av.open(io.BytesIO(data)) as container:
        return np.stack([f.to_ndarray(format="rgb24") for f in container.decode(video=0)])


def nal_layout(data: bytes) -> list[list[tuple[int, int]]]:
    """Return ``(type, size)`` of every NAL unit of every frame, checking each frame is
    exactly its NAL units and every filler unit is 0xFF bytes and its trailer."""
    table = sample_table(data)
    frames = []
    for start, size in table.samples:
        units, end = [], start
        for at, length, kind in nal_units(data, table.length_size, start, start + size):
            body = data[at + table.length_size:at + table.length_size + length]
            if kind == 12:
                assert body[0] == 0x0C and body[-1] == 0x80 and set(body[1:-1]) <= {0xFF}
            units.append((kind, length))
            end = at + table.length_size + length
        assert end == start + size
        frames.append(units)
    return frames


def test_every_delivery_of_an_mp4_has_its_own_bytes_and_the_same_frames(rendered):
    clips, _ = rendered
    for clip in clips:
        stored = clip.video.read_bytes()
        pictures = frames_of(stored)
        moov = [stored[at:at + size] for kind, at, size in mp4_boxes(stored) if kind == "moov"]
        hashes = set()
        layouts = []
        for seed in SEEDS:
            data = deliver(stored, "mp4", seed)
            assert len(data) == len(stored)
            assert data == deliver(stored, "mp4", seed)  # a range request reads these bytes
            hashes.add(hashlib.sha256(data).digest())
            # The index (every frame's size and offset) is the stored one, byte for byte.
            assert [data[at:at + size] for kind, at, size in mp4_boxes(data)
                    if kind == "moov"] == moov
            assert [k for k, _, _ in mp4_boxes(data)] == [k for k, _, _ in mp4_boxes(stored)]
            assert np.array_equal(frames_of(data), pictures)
            layout = nal_layout(data)
            # The frames' slices are the stored ones; only the filler after them changed.
            assert [[u for u in f if u[0] != 12] for f in layout] == \
                [[u for u in f if u[0] != 12] for f in nal_layout(stored)]
            layouts.append([sum(k == 12 for k, _ in f) for f in layout])
        assert len(hashes) == len(SEEDS) and hashlib.sha256(stored).digest() not in hashes
        assert len({tuple(counts) for counts in layouts}) == len(SEEDS)
        assert max(max(counts) for counts in layouts) > 1  # filler split into several units


def test_every_delivery_of_a_poster_has_its_own_bytes_and_the_same_picture(rendered):
    clips, _ = rendered
    for clip in clips:
        stored = clip.poster.read_bytes()
        picture = np.asarray(Image.open(io.BytesIO(stored)).convert("RGB"))
        hashes = set()
        for seed in SEEDS:
            data = deliver(stored, "png", seed)
            assert len(data) == len(stored) and data == deliver(stored, "png", seed)
            assert data[:33] == stored[:33]  # signature and header
            image = Image.open(io.BytesIO(data))
            image.verify()  # every chunk's CRC is right
            assert np.array_equal(np.asarray(Image.open(io.BytesIO(data)).convert("RGB")),
                                  picture)
            hashes.add(hashlib.sha256(data).digest())
            at = 8
            while at < len(data):  # walk the chunks: they tile the file
                length, kind = struct.unpack(">I4s", data[at:at + 8])
                crc = struct.unpack(">I", data[at + 8 + length:at + 12 + length])[0]
                assert crc == zlib.crc32(data[at + 4:at + 8 + length]) & 0xFFFFFFFF
                at += 12 + length
            assert at == len(data)
        assert len(hashes) == len(SEEDS)


def test_how_a_delivery_splits_its_padding_does_not_depend_on_the_clip(rendered):
    """Every stored frame keeps room for the most filler units and every poster for the
    most padding chunks, so the counts a delivery shows are drawn alike for a busy clip
    and a quiet one (a busier clip once had fuller frames, hence fewer units: countable)."""
    clips, _ = rendered
    per_clip_units, per_clip_chunks = [], []
    for clip in clips:
        stored = clip.video.read_bytes()
        table = sample_table(stored)
        for frame in nal_layout(stored):
            assert frame[-1][0] == 12 and sum(length for kind, length in frame[-1:]) + 4 >= \
                FILLER_ROOM
        poster = clip.poster.read_bytes()
        fills = [length for kind, length in _png_chunk_lengths(poster) if kind == b"fiLl"]
        assert fills and sum(length + 12 for length in fills) >= 12 * MAX_FILL_CHUNKS
        units, chunks = [], []
        for k in range(200):
            seed = hashlib.sha256(b"%d" % k).digest()
            data = deliver(stored, "mp4", seed)
            units += [sum(kind == 12 for kind, _ in f) for f in nal_layout(data)[:4]]
            chunks.append(sum(kind == b"fiLl" for kind, _ in
                              _png_chunk_lengths(deliver(poster, "png", seed))))
        assert table.samples
        per_clip_units.append(np.bincount(units, minlength=MAX_FILLERS + 1)[1:] / len(units))
        per_clip_chunks.append(np.bincount(chunks, minlength=MAX_FILL_CHUNKS + 1)[1:] / 200)
    # The same seeds draw the same counts for both clips: no clip's room cut a draw short.
    assert np.array_equal(per_clip_units[0], per_clip_units[1])
    assert np.array_equal(per_clip_chunks[0], per_clip_chunks[1])
    assert (per_clip_units[0] > 0).all() and (per_clip_chunks[0] > 0).all()


def _png_chunk_lengths(data: bytes):
    at = 8
    while at + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        yield kind, length
        at += length + 12


def test_every_delivery_of_a_payload_moves_values_by_a_unit_at_most(rendered):
    _, payloads = rendered
    for stored in payloads:
        fields = read(stored)
        hashes = set()
        for seed in SEEDS:
            data = deliver(stored, "motion", seed)
            assert len(data) == len(stored) and data == deliver(stored, "motion", seed)
            moved = read(data)
            step = fields["step"]
            change = np.abs(moved["positions"] - fields["positions"]) / step
            assert change.max() == pytest.approx(1.0)
            assert 0.5 < (change > 0.5).mean() < 0.8  # about two thirds of the values
            assert np.abs(moved["targets"] - fields["targets"]).max() <= step * 1.0001
            assert np.abs(moved["windows"] - fields["windows"]).max() <= 1.0001 / 8192
            assert np.allclose(moved["distances"], fields["distances"], rtol=1.0001 / 2048)
            for name in ("parents", "sides", "stick_radii", "body_radii"):
                assert np.array_equal(moved[name], fields[name])
            hashes.add(hashlib.sha256(data).digest())
        assert len(hashes) == len(SEEDS)


def test_unknown_kinds_and_short_seeds_are_refused(rendered):
    clips, _ = rendered
    with pytest.raises(ValueError, match="no per-delivery bytes for 'webm'"):
        deliver(b"", "webm", SEEDS[0])
    with pytest.raises(ValueError, match="at least 16 bytes"):
        deliver(clips[0].video.read_bytes(), "mp4", b"short")
