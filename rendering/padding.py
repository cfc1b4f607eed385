"""Pad finished files to an exact byte size with parts every reader skips.

A participant sees a clip's byte size (``Content-Length``) before a frame plays, so every
clip of one length and resolution is written to one size: the encoder keeps the rate
constant, and the few bytes left over are a ``free`` box (mp4), a ``Void`` element inside
the Segment (WebM), a comment extension (GIF) or a private ancillary chunk (PNG). Each is
defined by its format as ignorable, so the picture is untouched.
"""

from __future__ import annotations

import struct
import zlib
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
