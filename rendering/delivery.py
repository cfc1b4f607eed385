"""Per-delivery bytes: every delivery of a stored clip file is a file of its own.

A participant's browser, or a script, can hash what it is sent. Were every delivery the
stored file, a repeated trial's clip would be byte for byte the earlier one and a catch
clip the same bytes for everyone, so hashes would answer the repeat and attention checks.
:func:`deliver` turns a stored file and a delivery's seed into that delivery's bytes: of
the same size, with the same pictures, frames and tables a reader parses, and a layout of
its own of what every reader skips:

- ``mp4``: each frame's trailing filler data (H.264 NAL units of type 12, which decoders
  skip, after the frame's slices: H.264 allows filler only after a picture's first slice)
  is split into a seeded number of filler NAL units of seeded lengths, and the file's
  ``free`` boxes hold seeded bytes. Every frame keeps its byte size, so the ``stsz``
  table, the chunk offsets and the file's size are those of the stored file.
- ``png``: the poster's padding chunks (``fiLl``) hold seeded bytes, split over a seeded
  number of chunks of the same total size.
- ``motion`` (the in-browser player's payload): :func:`rendering.player.dither`, one
  quantisation unit (a 4096th of the figure's height) up or down on a seeded two thirds
  of its positions.

It is a pure, cheap function of ``(stored bytes, seed)``: a server can run it per request
(the byte ranges of one delivery then always agree) or write each delivery once as its
own object. The seed must be unguessable and differ per delivery (the Django side takes
an HMAC of its secret and the trial item's token).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from rendering.padding import PaddingError, mp4_boxes, nal_units, sample_table
from rendering.player import dither

FILLER = 12  # H.264 nal_unit_type of filler data
MAX_FILLERS = 4  # filler NAL units a frame's filler data is split into, at most
MAX_FILL_CHUNKS = 3  # PNG padding chunks, at most
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FILL_CHUNK = b"fiLl"


def rng_of(seed: bytes) -> np.random.Generator:
    """Return the random generator of a delivery's seed (at least 16 bytes)."""
    if len(seed) < 16:
        raise ValueError(f"a delivery seed needs at least 16 bytes; got {len(seed)}")
    return np.random.default_rng(int.from_bytes(seed[:32], "big"))


def _filler_run(data: bytes, start: int, size: int, length_size: int) -> tuple[int, int]:
    """Return ``(offset, bytes)`` of the filler NAL units that end a frame (0 bytes when
    it ends otherwise, or its NAL units do not fill it exactly)."""
    run = None
    end = start + size
    stop = start
    for at, length, kind in nal_units(data, length_size, start, end):
        if kind == FILLER:
            run = at if run is None else run
        else:
            run = None
        stop = at + length_size + length
    if run is None or stop != end:
        return end, 0
    return run, end - run


def vary_mp4(data: bytes, seed: bytes) -> bytes:
    """Return this delivery's mp4: the frames' filler laid out anew, ``free`` boxes refilled."""
    table = sample_table(data)
    rng = rng_of(seed)
    out = bytearray(data)
    width = table.length_size
    smallest = width + 2  # a filler NAL unit of no 0xFF bytes: length, header, trailer
    # Per frame: how many units (the first draw), and where the others start.
    draws = rng.random((len(table.samples), MAX_FILLERS)).tolist()
    for (start, size), draw in zip(table.samples, draws):
        at, run = _filler_run(data, start, size, width)
        if run < smallest:
            continue
        units = min(1 + int(draw[0] * MAX_FILLERS), run // smallest)
        rest = run - units * smallest
        edges = [0, *sorted(int(u * (rest + 1)) for u in draw[1:units]), rest]
        out[at:at + run] = b"\xff" * run
        for first, last in zip(edges, edges[1:]):
            length = last - first + smallest
            out[at:at + width] = (length - width).to_bytes(width, "big")
            out[at + width] = FILLER  # forbidden bit 0, nal_ref_idc 0
            out[at + length - 1] = 0x80  # the RBSP trailing bits
            at += length
    for kind, start, size in mp4_boxes(data):
        if kind in ("free", "skip") and size > 8:
            out[start + 8:start + size] = rng.bytes(size - 8)
    return bytes(out)


def _chunks(data: bytes):
    """Yield ``(type, offset, total size)`` of a PNG's chunks."""
    at = len(PNG_SIGNATURE)
    while at + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        yield kind, at, length + 12
        at += length + 12


def _chunk(kind: bytes, body: bytes) -> bytes:
    crc = zlib.crc32(kind + body) & 0xFFFFFFFF
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", crc)


def vary_png(data: bytes, seed: bytes) -> bytes:
    """Return this delivery's poster: its padding chunks of seeded bytes and number."""
    if not data.startswith(PNG_SIGNATURE):
        raise PaddingError("not a PNG")
    chunks = list(_chunks(data))
    fills = [(at, size) for kind, at, size in chunks if kind == FILL_CHUNK]
    if not fills:
        return data
    total = sum(size for _, size in fills)
    rng = rng_of(seed)
    units = int(min(rng.integers(1, MAX_FILL_CHUNKS + 1), total // 12))
    rest = total - 12 * units
    cuts = np.sort(rng.integers(0, rest + 1, size=units - 1))
    bodies = (np.diff(np.concatenate([[0], cuts, [rest]]))).tolist()
    padding = b"".join(_chunk(FILL_CHUNK, rng.bytes(n)) for n in bodies)
    kept = b"".join(data[at:at + size] for kind, at, size in chunks
                    if kind not in (FILL_CHUNK, b"IEND"))
    end = [data[at:at + size] for kind, at, size in chunks if kind == b"IEND"]
    return PNG_SIGNATURE + kept + padding + b"".join(end)


VARIANTS = {"mp4": vary_mp4, "png": vary_png, "motion": lambda data, seed: dither(data,
                                                                                   rng_of(seed))}


def deliver(data: bytes, kind: str, seed: bytes) -> bytes:
    """Return the bytes of one delivery of a stored ``kind`` file (``mp4``, ``png`` or
    ``motion``); see the module docstring."""
    if kind not in VARIANTS:
        raise ValueError(f"no per-delivery bytes for {kind!r} files; known: "
                         f"{', '.join(VARIANTS)}")
    return VARIANTS[kind](data, seed)
