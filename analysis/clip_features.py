"""What a script can read of one delivery of a clip without decoding a picture, in three
families, and the keys that tell whether two deliveries hold the same clip.

- ``delivery`` (:func:`delivery_features`): how the bytes are sent and packed: sizes,
  response headers, the MP4's boxes, duration, picture size and frame-size table
  (``stsz``), how its filler is split, the poster's size, picture size and chunk layout,
  the payload's size and header. None of it may tell anything about a clip.
- ``bitstream`` (:func:`bitstream_features`): the true sizes of the H.264 frames (every
  NAL unit but filler data, which a parser skips as a decoder does) and of the poster's
  image data (its ``IDAT`` chunks). These follow what the clip shows: a busy frame
  compresses to more bytes.
- ``payload`` (:func:`payload_features`): the in-browser player's joints, as numbers:
  how much bone lengths vary, speeds, accelerations, jerk, the ranges of the values,
  how far the figure travels. This is the motion itself.

:func:`content_keys` returns, per file, a key of what a delivery shows (the slices of the
H.264 stream, the poster's image data, the payload's values): two deliveries of one clip
share them whatever their bytes (:func:`same_content`), as a viewer recognises the clip.

Plain Python and NumPy (and the file layouts of :mod:`rendering`); the Django side
(``studyapp.results.audit``) fetches the files.
"""

from __future__ import annotations

import hashlib
import struct

import numpy as np

from rendering.padding import PaddingError, nal_units, sample_table
from rendering.player import PayloadError, read

FAMILIES = ("delivery", "bitstream", "payload")
FILLER = 12  # H.264 nal_unit_type of filler data
# Headers whose values differ with the moment, not the clip.
MOMENT_HEADERS = {"date", "expires", "server", "connection", "keep-alive", "set-cookie", "vary",
                  "x-request-id"}
CONTAINERS = {b"moov", b"trak", b"mdia", b"minf", b"stbl", b"edts", b"dinf", b"udta"}
PAYLOAD_TOLERANCE = 2  # payload units (a 4096th of the figure's height): two dithers apart


def _boxes(data: bytes, start: int = 0, end: int | None = None):
    """Yield ``(type, payload start, box end)`` of the ISO-BMFF boxes in ``data[start:end]``."""
    end = len(data) if end is None else end
    at = start
    while at + 8 <= end:
        size, kind = struct.unpack(">I4s", data[at:at + 8])
        header = 8
        if size == 1 and at + 16 <= end:
            size = struct.unpack(">Q", data[at + 8:at + 16])[0]
            header = 16
        elif size == 0:
            size = end - at
        if size < header or at + size > end:
            return
        yield kind, at + header, at + size
        at += size


def _stats(prefix: str, values) -> dict[str, float]:
    values = np.asarray(values, dtype=float)
    if not values.size:
        return {}
    return {f"{prefix}_mean": float(values.mean()), f"{prefix}_sd": float(values.std()),
            f"{prefix}_max": float(values.max()), f"{prefix}_min": float(values.min()),
            f"{prefix}_p90": float(np.percentile(values, 90))}


def mp4_features(data: bytes) -> dict[str, float]:
    """Return what an MP4 file shows of itself: box sizes, duration, picture size, frames."""
    out = {"mp4_boxes": 0.0, "mp4_bytes_free": 0.0}
    sizes: list[int] = []

    def walk(start, end, depth):
        for kind, payload, stop in _boxes(data, start, end):
            name = kind.decode("latin-1", "replace")
            out["mp4_boxes"] += 1
            out[f"box_{name}_bytes"] = out.get(f"box_{name}_bytes", 0.0) + (stop - payload)
            if kind in (b"free", b"skip"):
                out["mp4_bytes_free"] += stop - payload
            if kind in CONTAINERS and depth < 8:
                walk(payload, stop, depth + 1)
            elif kind == b"mvhd" and stop - payload >= 20:
                version = data[payload]
                if version == 1:
                    scale, duration = struct.unpack(">IQ", data[payload + 20:payload + 32])
                else:
                    scale, duration = struct.unpack(">II", data[payload + 12:payload + 20])
                out["duration_s"] = duration / scale if scale else 0.0
            elif kind == b"tkhd" and stop - payload >= 84:
                width, height = struct.unpack(">II", data[stop - 8:stop])
                out["width"], out["height"] = width / 65536, height / 65536
            elif kind == b"stsz" and stop - payload >= 12:
                fixed, count = struct.unpack(">II", data[payload + 4:payload + 12])
                if fixed:
                    sizes.extend([fixed] * count)
                else:
                    sizes.extend(struct.unpack(f">{count}I", data[payload + 12:payload + 12 + 4 * count]))

    walk(0, len(data), 0)
    if sizes:
        frames = np.asarray(sizes, dtype=float)
        out.update(frames=float(len(frames)), frame_bytes_first=float(frames[0]),
                   **_stats("frame_bytes", frames))
    return out


def _frames(data: bytes):
    """Yield ``(sample size, [(NAL type, size with prefix)])`` per H.264 frame, or nothing
    when the file is not an mp4 laid out as the video writer makes them."""
    try:
        table = sample_table(data)
    except (PaddingError, struct.error, IndexError):
        return
    width = table.length_size
    for start, size in table.samples:
        yield size, [(kind, width + length)
                     for _, length, kind in nal_units(data, width, start, start + size)]


def filler_features(data: bytes) -> dict[str, float]:
    """Return how each frame's filler is split: filler NAL units per frame."""
    counts = [sum(kind == FILLER for kind, _ in nals) for _, nals in _frames(data)]
    return _stats("filler_units", counts) if counts else {}


def _png_chunks(data: bytes):
    at = 8
    while at + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        yield kind, data[at + 8:at + 8 + length]
        at += length + 12


def png_features(data: bytes) -> dict[str, float]:
    """Return a poster's byte size, picture size and chunk layout (not its picture)."""
    out = {"poster_bytes": float(len(data))}
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        width, height = struct.unpack(">II", data[16:24])
        out.update(poster_width=float(width), poster_height=float(height),
                   poster_depth=float(data[24]), poster_colour_type=float(data[25]))
        kinds = [kind for kind, _ in _png_chunks(data)]
        out["poster_chunks"] = float(len(kinds))
        out["poster_idat_chunks"] = float(kinds.count(b"IDAT"))
    return out


def header_features(headers: dict, prefix: str) -> dict[str, float]:
    """Return the lengths of the response headers a page could read (not the moment's)."""
    kept = {k.lower(): str(v) for k, v in headers.items() if k.lower() not in MOMENT_HEADERS}
    out = {f"{prefix}_header_bytes": float(sum(len(k) + len(v) for k, v in kept.items())),
           f"{prefix}_headers": float(len(kept))}
    for name, value in kept.items():
        out[f"{prefix}_h_{name}_len"] = float(len(value))
        if name == "content-length" and value.isdigit():
            out[f"{prefix}_content_length"] = float(value)
    return out


def payload_header_features(data: bytes) -> dict[str, float]:
    """Return a payload's size and the numbers of its header (the set's camera rule)."""
    out = {"motion_bytes": float(len(data))}
    try:
        fields = read(data)
    except PayloadError:
        return out
    for name in ("frames", "joints", "fps", "step", "azimuth", "elevation", "fov", "distance",
                 "window_step", "height", "shadow_slant", "stick_bone_radius"):
        out[f"motion_{name}"] = float(fields[name])
    return out


def delivery_features(files: dict) -> dict[str, float]:
    """Return the ``delivery`` family of one delivery: ``files`` maps ``mp4``, ``png`` and
    ``motion`` to ``(headers, bytes)`` (those a study serves)."""
    headers, video = files["mp4"]
    out = {"video_bytes": float(len(video)), **mp4_features(video), **filler_features(video),
           **header_features(headers, "video")}
    if "png" in files:
        headers, poster = files["png"]
        out.update(png_features(poster))
        out.update(header_features(headers, "poster"))
    if "motion" in files:
        headers, motion = files["motion"]
        out.update(payload_header_features(motion))
        out.update(header_features(headers, "motion"))
    return out


def bitstream_features(files: dict) -> dict[str, float]:
    """Return the ``bitstream`` family: true frame sizes (no filler) and the poster's
    image data size."""
    out = {}
    sizes = [sum(length for kind, length in nals if kind != FILLER)
             for _, nals in _frames(files["mp4"][1])]
    if sizes:
        frames = np.asarray(sizes, dtype=float)
        out.update(_stats("true_frame_bytes", frames[1:] if len(frames) > 1 else frames))
        out["true_keyframe_bytes"] = float(frames[0])
        out["true_frame_bytes_step"] = float(np.abs(np.diff(frames)).mean()) if len(frames) > 1 else 0.0
        out["true_frame_bytes_cv"] = float(frames.std() / max(frames.mean(), 1.0))
    if "png" in files:
        out["poster_image_bytes"] = float(sum(len(body) for kind, body in
                                              _png_chunks(files["png"][1]) if kind == b"IDAT"))
    return out


def payload_features(files: dict) -> dict[str, float]:
    """Return the ``payload`` family (empty without a payload): statistics of the motion
    a script reads from the in-browser player's numbers."""
    if "motion" not in files:
        return {}
    try:
        fields = read(files["motion"][1])
    except PayloadError:
        return {}
    joints = fields["positions"].astype(float)  # (T, J, 3) metres, z up, on the floor
    parents = fields["parents"]
    fps = float(fields["fps"]) or 1.0
    bones = [j for j in range(len(parents)) if parents[j] >= 0]
    out = {}
    if bones:
        lengths = np.linalg.norm(joints[:, bones] - joints[:, parents[bones]], axis=-1)
        spread = lengths.std(axis=0) / np.maximum(lengths.mean(axis=0), 1e-6)
        out.update(_stats("bone_length_spread", spread))
    if len(joints) > 1:
        out.update(_stats("speed", np.linalg.norm(np.diff(joints, axis=0), axis=-1) * fps))
    if len(joints) > 2:
        out.update(_stats("acceleration",
                          np.linalg.norm(np.diff(joints, 2, axis=0), axis=-1) * fps ** 2))
    if len(joints) > 3:
        out.update(_stats("jerk", np.linalg.norm(np.diff(joints, 3, axis=0), axis=-1) * fps ** 3))
    for axis, name in enumerate("xyz"):
        out[f"range_{name}"] = float(np.ptp(joints[..., axis]))
    out.update(_stats("height", joints[..., 2].max(axis=1) - joints[..., 2].min(axis=1)))
    out["z_max"] = float(joints[..., 2].max())
    out["z_min"] = float(joints[..., 2].min())
    out["z_mean"] = float(joints[..., 2].mean())
    centre = joints.mean(axis=1)
    out["travel"] = float(np.linalg.norm(centre[-1, :2] - centre[0, :2]))
    out["path"] = float(np.linalg.norm(np.diff(centre, axis=0), axis=-1).sum())
    out["camera_path"] = float(np.linalg.norm(np.diff(fields["targets"], axis=0), axis=-1).sum())
    # The frame's window over the canvas (how the clip's shot keeps its figure inside).
    out["window_path"] = float(np.linalg.norm(np.diff(fields["windows"], axis=0), axis=-1).sum())
    out["window_reach"] = float(np.abs(fields["windows"]).max()) if len(fields["windows"]) else 0.0
    return out


FEATURES = {"delivery": delivery_features, "bitstream": bitstream_features,
            "payload": payload_features}


def features(files: dict) -> dict[str, dict[str, float]]:
    """Return ``{family: {feature: value}}`` of one delivery (see the module docstring)."""
    return {family: make(files) for family, make in FEATURES.items()}


def file_hashes(files: dict) -> dict[str, str]:
    """Return the sha256 of each file of a delivery, as a script would hash them."""
    return {ext: hashlib.sha256(body).hexdigest() for ext, (_, body) in files.items()}


def content_keys(files: dict) -> dict:
    """Return per file what it shows, the same for every delivery of a clip: a hash of the
    H.264 stream without filler, of the poster's image data, and the payload's int16
    values (compare these with :func:`same_content`: a delivery's dither moves them)."""
    keys = {}
    data = files["mp4"][1]
    digest = hashlib.sha256()
    found = False
    try:
        table = sample_table(data)
    except (PaddingError, struct.error, IndexError):
        table = None
    if table is not None:
        for start, size in table.samples:
            for at, length, kind in nal_units(data, table.length_size, start, start + size):
                if kind != FILLER:
                    found = True
                    digest.update(data[at:at + table.length_size + length])
    keys["mp4"] = digest.hexdigest() if found else hashlib.sha256(data).hexdigest()
    if "png" in files:
        idat = b"".join(body for kind, body in _png_chunks(files["png"][1]) if kind == b"IDAT")
        keys["png"] = hashlib.sha256(idat).hexdigest()
    if "motion" in files:
        body = files["motion"][1]
        try:
            fields = read(body)
            keys["motion"] = np.rint(fields["positions"] / fields["step"]).astype(np.int32)
        except PayloadError:
            keys["motion"] = hashlib.sha256(body).hexdigest()
    return keys


def same_content(ext: str, a, b) -> bool:
    """Return whether two content keys of ``ext`` files (:func:`content_keys`) show the
    same clip: equal hashes, or payload values at most ``PAYLOAD_TOLERANCE`` units apart."""
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return a.shape == b.shape and int(np.abs(a - b).max(initial=0)) <= PAYLOAD_TOLERANCE
    return isinstance(a, str) and a == b
