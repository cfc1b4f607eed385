"""Pad finished files to an exact byte size with parts every reader skips.

A participant sees a clip's byte size (``Content-Length``) before a frame plays, so every
clip of one length and resolution is written to one size: the encoder keeps the rate
constant, and the few bytes left over are a ``free`` box (mp4), a ``Void`` element inside
the Segment (WebM), a comment extension (GIF) or a private ancillary chunk (PNG). Each is
defined by its format as ignorable, so the picture is untouched.

An mp4 also lists the byte size of every frame (its ``stsz`` box), which anyone can read:
:func:`equalise_mp4_frames` makes every keyframe one size and every other frame another,
by lengthening each frame's H.264 filler data (NAL unit type 12, which decoders skip), so
that table is the same for every clip of one length.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from pathlib import Path


class PaddingError(ValueError):
    """A file is already larger than the size asked for, or of a kind this cannot pad."""


def _grow(path: Path, size: int, smallest: int) -> int:
    """Return how many bytes ``path`` lacks to reach ``size``, refusing what cannot be padded."""
    have = path.stat().st_size
    missing = size - have
    if missing < 0 or 0 < missing < smallest:
        raise PaddingError(
            f"{path.name} is {have} bytes; it cannot be padded to {size} (needs {smallest}+ "
            f"bytes of room or none)"
        )
    return missing


def pad_mp4(path: str | Path, size: int) -> None:
    """Append a top-level ``free`` box so that the mp4 is exactly ``size`` bytes."""
    path = Path(path)
    missing = _grow(path, size, 8)
    if missing:
        with open(path, "ab") as handle:
            handle.write(struct.pack(">I4s", missing, b"free") + bytes(missing - 8))


def _ebml_size(value: int, width: int = 8) -> bytes:
    """Return an EBML variable-size integer of ``width`` bytes."""
    return ((1 << (7 * width)) | value).to_bytes(width, "big")


def pad_webm(path: str | Path, size: int) -> None:
    """Grow a WebM's Segment by a ``Void`` element at its end to make ``size`` bytes.

    The Segment is the file's last top-level element, so a Void appended to the file
    belongs to it once the Segment's size field counts it (FFmpeg writes that field with
    8 bytes, or as unknown, which needs no change).
    """
    path = Path(path)
    missing = _grow(path, size, 9)
    if not missing:
        return
    data = bytearray(path.read_bytes())
    at = data.find(b"\x18\x53\x80\x67")  # the Segment's ID
    if at < 0 or data[at + 4] != 0x01:
        raise PaddingError(f"{path.name}: no Segment with an 8-byte size to grow")
    start = at + 12
    length = int.from_bytes(data[at + 5:at + 12], "big")
    unknown = length == (1 << 56) - 1
    if not unknown and start + length != len(data):
        raise PaddingError(f"{path.name}: the Segment does not end the file")
    void = b"\xec" + _ebml_size(missing - 9) + bytes(missing - 9)
    if not unknown:
        data[at + 4:at + 12] = _ebml_size(length + missing)
    path.write_bytes(bytes(data) + void)


def pad_gif(path: str | Path, size: int) -> None:
    """Insert a comment extension before the GIF's trailer to make ``size`` bytes."""
    path = Path(path)
    missing = _grow(path, size, 5)
    if not missing:
        return
    data = path.read_bytes()
    if not data.endswith(b"\x3b"):
        raise PaddingError(f"{path.name}: no GIF trailer to pad before")
    # Introducer, label, sub-blocks (a length byte each), terminator: 3 bytes besides data.
    blocks, room = [], missing - 3
    while room > 0:
        take = min(255, room - 1)
        if room - 1 - take == 1:  # never leave room for a length byte with nothing after it
            take -= 1
        blocks.append(bytes([take]) + b" " * take)
        room -= take + 1
    comment = b"\x21\xfe" + b"".join(blocks) + b"\x00"
    path.write_bytes(data[:-1] + comment + b"\x3b")


def pad_png(path: str | Path, size: int) -> None:
    """Insert a private ancillary chunk (``fiLl``) before ``IEND`` to make ``size`` bytes."""
    path = Path(path)
    missing = _grow(path, size, 12)
    if not missing:
        return
    data = path.read_bytes()
    end = data.rfind(b"IEND") - 4
    if end < 8:
        raise PaddingError(f"{path.name}: no IEND chunk")
    body = bytes(missing - 12)
    chunk = struct.pack(">I", len(body)) + b"fiLl" + body
    chunk += struct.pack(">I", zlib.crc32(b"fiLl" + body) & 0xFFFFFFFF)
    path.write_bytes(data[:end] + chunk + data[end:])


FILLER = 12  # H.264 nal_unit_type of filler data


def _child(data: bytes, start: int, end: int, kind: bytes):
    for found, payload, stop in _mp4_boxes(data, start, end):
        if found == kind:
            return payload, stop
    return None


def _mp4_boxes(data: bytes, start: int, end: int):
    at = start
    while at + 8 <= end:
        size, kind = struct.unpack(">I4s", data[at:at + 8])
        header = 8
        if size == 1:
            size = struct.unpack(">Q", data[at + 8:at + 16])[0]
            header = 16
        elif size == 0:
            size = end - at
        if size < header or at + size > end:
            raise PaddingError("an mp4 box runs past its parent")
        yield kind, at + header, at + size
        at += size


def nal_units(data: bytes, length_size: int, start: int = 0, end: int | None = None):
    """Yield ``(offset, size, type)`` of the length-prefixed NAL units of an H.264 sample
    ``data[start:end]`` (``size`` without the length prefix)."""
    end = len(data) if end is None else end
    at = start
    while at + length_size < end:
        size = int.from_bytes(data[at:at + length_size], "big")
        yield at, size, data[at + length_size] & 0x1F
        at += length_size + size


def _nal_units(sample: bytes, length_size: int):
    return nal_units(sample, length_size)


def _has_filler(sample: bytes, length_size: int) -> bool:
    return any(kind == FILLER for _, _, kind in _nal_units(sample, length_size))


def _grown(sample: bytes, by: int, length_size: int) -> bytes:
    """Return an H.264 sample (length-prefixed NAL units) ``by`` bytes longer: its last
    filler NAL unit lengthened, or a filler NAL unit appended."""
    if not by:
        return sample
    fillers = [(at, size) for at, size, kind in _nal_units(sample, length_size)
               if kind == FILLER]
    filler = fillers[-1] if fillers else None
    if filler is not None:
        start, size = filler
        end = start + length_size + size  # the filler's last byte is its 0x80 trailer
        head = (size + by).to_bytes(length_size, "big")
        return (sample[:start] + head + sample[start + length_size:end - 1] + b"\xff" * by
                + sample[end - 1:])
    if by < length_size + 2:
        raise PaddingError(f"a frame without filler data cannot grow by {by} bytes")
    body = b"\x0c" + b"\xff" * (by - length_size - 2) + b"\x80"
    return sample + len(body).to_bytes(length_size, "big") + body


@dataclass
class SampleTable:
    """Where an mp4's frames and the tables that place them are (see :func:`sample_table`).

    ``samples`` are ``(offset, size)`` of each frame in the file, ``keys`` the indices of
    keyframes, ``length_size`` the byte width of each NAL unit's length prefix; the rest
    are offsets of the tables' entries, for rewriting them.
    """

    samples: list[tuple[int, int]]
    keys: set[int]
    length_size: int
    per_chunk: list[int]
    mdat: tuple[int, int]  # payload start and end of the mdat box
    sizes_at: int  # the stsz box's payload
    offsets_at: int  # the stco box's payload
    mdia: tuple[int, int]
    stsd: tuple[int, int] | None
    fixed_size: bool = False  # stsz gives one size for every frame


def sample_table(data: bytes, name: str = "the mp4") -> SampleTable:
    """Return where the frames of a one-track H.264 mp4 are.

    The file must hold its index first (``+faststart``) and its frames in order in one
    ``mdat``, as the video writer makes it; raise :class:`PaddingError` otherwise.
    """
    top = {kind: (payload, stop) for kind, payload, stop in _mp4_boxes(data, 0, len(data))}
    if b"moov" not in top or b"mdat" not in top or top[b"moov"][0] > top[b"mdat"][0]:
        raise PaddingError(f"{name}: not an mp4 with its index first")
    box = top[b"moov"]
    for kind in (b"trak", b"mdia", b"minf", b"stbl"):
        box = _child(data, *box, kind)
        if box is None:
            raise PaddingError(f"{name}: no {kind.decode()} box")
        if kind == b"mdia":
            mdia = box
    stbl = box
    tables = {kind: _child(data, *stbl, kind) for kind in (b"stsz", b"stco", b"stsc", b"stss",
                                                            b"stsd")}
    if tables[b"stsz"] is None or tables[b"stco"] is None or tables[b"stsc"] is None:
        raise PaddingError(f"{name}: no frame size, chunk or offset table")
    sizes_at = tables[b"stsz"][0]
    fixed, count = struct.unpack(">II", data[sizes_at + 4:sizes_at + 12])
    if fixed:
        sizes = [fixed] * count
    else:
        sizes = list(struct.unpack(f">{count}I", data[sizes_at + 12:sizes_at + 12 + 4 * count]))
    offsets_at = tables[b"stco"][0]
    chunks = struct.unpack(">I", data[offsets_at + 4:offsets_at + 8])[0]
    offsets = list(struct.unpack(f">{chunks}I", data[offsets_at + 8:offsets_at + 8 + 4 * chunks]))
    runs_at = tables[b"stsc"][0]
    runs = struct.unpack(">I", data[runs_at + 4:runs_at + 8])[0]
    per_chunk = [0] * chunks
    rows = [struct.unpack(">III", data[runs_at + 8 + 12 * k:runs_at + 20 + 12 * k])
            for k in range(runs)]
    for k, (first, samples, _) in enumerate(rows):
        last = rows[k + 1][0] - 1 if k + 1 < runs else chunks
        for chunk in range(first - 1, last):
            per_chunk[chunk] = samples
    if sum(per_chunk) != count:
        raise PaddingError(f"{name}: its chunk table does not add up to its frames")
    keys = set(range(count))
    if tables[b"stss"] is not None:
        at = tables[b"stss"][0]
        n = struct.unpack(">I", data[at + 4:at + 8])[0]
        keys = {k - 1 for k in struct.unpack(f">{n}I", data[at + 8:at + 8 + 4 * n])}
    length_size = 4
    avcc = data.find(b"avcC", *tables[b"stsd"]) if tables[b"stsd"] else -1
    if avcc >= 0:
        length_size = (data[avcc + 8] & 0x3) + 1
    samples, index = [], 0
    mdat_start, mdat_end = top[b"mdat"]
    expected = mdat_start
    for chunk, n in enumerate(per_chunk):
        if offsets[chunk] != expected:
            raise PaddingError(f"{name}: its frames are not one run in the mdat box")
        for _ in range(n):
            samples.append((expected, sizes[index]))
            expected += sizes[index]
            index += 1
    if expected != mdat_end:
        raise PaddingError(f"{name}: the mdat box holds more than its frames")
    return SampleTable(samples, keys, length_size, per_chunk, (mdat_start, mdat_end),
                       sizes_at, offsets_at, mdia, tables[b"stsd"], bool(fixed))


def equalise_mp4_frames(path: str | Path, key_size: int | None = None,
                        frame_size: int | None = None) -> None:
    """Make every keyframe of a one-track H.264 mp4 ``key_size`` bytes and every other
    frame ``frame_size`` bytes (default: the largest of each kind in the file); see the
    module docstring. Raise :class:`PaddingError` when a frame is larger than its size.

    The file must be laid out as :func:`sample_table` reads it; only sizes and offsets
    change in the index.
    """
    path = Path(path)
    data = path.read_bytes()
    table = sample_table(data, path.name)
    if table.fixed_size:
        return  # every frame already has one size
    keys, length_size, count = table.keys, table.length_size, len(table.samples)
    sizes = [size for _, size in table.samples]
    samples = [data[at:at + size] for at, size in table.samples]
    largest = {True: max((sizes[k] for k in keys), default=0),
               False: max((sizes[k] for k in range(count) if k not in keys), default=0)}
    widest = {True: key_size or largest[True], False: frame_size or largest[False]}
    for key in (True, False):
        if largest[key] > widest[key]:
            kind = "keyframe" if key else "frame"
            raise PaddingError(f"{path.name}: a {kind} of {largest[key]} bytes is over its "
                               f"budget of {widest[key]}")
        # A frame without filler data grows only by a whole filler NAL unit (length,
        # header, trailer): when one would have to grow by less, every frame of its
        # kind grows by that much more.
        short = [k for k in range(count) if (k in keys) == key
                 and 0 < widest[key] - sizes[k] < length_size + 2
                 and not _has_filler(samples[k], length_size)]
        if short and (key_size if key else frame_size):
            raise PaddingError(f"{path.name}: a frame without filler data is a few bytes "
                               f"short of its budget")
        if short:
            widest[key] += length_size + 2
    grown = [_grown(sample, widest[k in keys] - len(sample), length_size)
             for k, sample in enumerate(samples)]
    new_sizes = [len(sample) for sample in grown]
    mdat_start, mdat_end = table.mdat
    new_offsets, at = [], mdat_start
    index = 0
    for n in table.per_chunk:
        new_offsets.append(at)
        at += sum(new_sizes[index:index + n])
        index += n
    out = bytearray(data[:mdat_start])
    _rewrite_bit_rates(out, data, table.mdia, table.stsd, new_sizes)
    sizes_at, offsets_at, chunks = table.sizes_at, table.offsets_at, len(table.per_chunk)
    out[sizes_at + 12:sizes_at + 12 + 4 * count] = struct.pack(f">{count}I", *new_sizes)
    out[offsets_at + 8:offsets_at + 8 + 4 * chunks] = struct.pack(f">{chunks}I", *new_offsets)
    header = mdat_start - 8
    if struct.unpack(">I", data[header:header + 4])[0] != mdat_end - header:
        raise PaddingError(f"{path.name}: an mdat box with a 64-bit size is not handled")
    out[header:header + 4] = struct.pack(">I", 8 + sum(new_sizes))
    path.write_bytes(bytes(out) + b"".join(grown) + data[mdat_end:])


def _rewrite_bit_rates(out: bytearray, data: bytes, mdia, stsd, sizes) -> None:
    """Set the ``btrt`` box (buffer size, maximum and mean bit rate, which the muxer
    measured on the frames before padding) from the padded frames."""
    at = data.find(b"btrt", *stsd) if stsd else -1
    mdhd = _child(data, *mdia, b"mdhd")
    if at < 0 or mdhd is None:
        return
    version = data[mdhd[0]]
    if version == 1:
        scale, duration = struct.unpack(">IQ", data[mdhd[0] + 20:mdhd[0] + 32])
    else:
        scale, duration = struct.unpack(">II", data[mdhd[0] + 12:mdhd[0] + 20])
    seconds = duration / scale if scale else 0.0
    rate = int(round(8 * sum(sizes) / seconds)) if seconds else 0
    out[at + 4:at + 16] = struct.pack(">III", max(sizes, default=0), rate, rate)


PADDERS = {"mp4": pad_mp4, "webm": pad_webm, "gif": pad_gif, "png": pad_png}


def pad(path: str | Path, size: int) -> None:
    """Pad a file of a known kind (by suffix) to exactly ``size`` bytes."""
    path = Path(path)
    kind = path.suffix[1:].lower()
    if kind not in PADDERS:
        raise PaddingError(f"cannot pad {path.name}: not one of {', '.join(PADDERS)}")
    PADDERS[kind](path, size)


def mp4_boxes(data: bytes, start: int = 0, end: int | None = None) -> list[tuple[str, int, int]]:
    """Return ``(type, offset, size)`` of the boxes between ``start`` and ``end``."""
    end = len(data) if end is None else end
    boxes = []
    while start + 8 <= end:
        size, kind = struct.unpack(">I4s", data[start:start + 8])
        if size == 1:
            size = struct.unpack(">Q", data[start + 8:start + 16])[0]
        elif size == 0:
            size = end - start
        if size < 8:
            break
        boxes.append((kind.decode("latin-1"), start, size))
        start += size
    return boxes
