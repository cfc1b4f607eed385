"""The blindness audit: can a simple classifier tell clips apart by what a participant's
browser receives?

For every clip a study serves, :func:`clip_features` reads what is observable over HTTP:
the byte size and the response headers, the MP4's duration, picture size and the sizes of
its boxes and of its frames (the ``stsz`` table: a complex motion can make larger frames),
and the poster's byte size and picture size. :func:`audit` fits a logistic regression to
predict a label (real vs generated, catch vs not) from those features with stratified
k-fold cross-validation and compares its held-out accuracy with chance (always guessing
the larger class). It fails when the accuracy beats chance by more than
``max(MIN_MARGIN, Z * standard error of chance)``: more than a few clips guessed right by
luck, too few to be luck.

Plain Python and NumPy: the Django side (``studyapp.survey.audit``) fetches the clips.
"""

from __future__ import annotations

import math
import struct

import numpy as np

MIN_MARGIN = 0.05
Z = 2.33  # one-sided 99 %: a leak this clear is no coincidence
FOLDS = 5
# Headers whose values differ with the moment, not the clip.
MOMENT_HEADERS = {"date", "expires", "server", "connection", "keep-alive", "set-cookie", "vary",
                  "x-request-id"}
CONTAINERS = {b"moov", b"trak", b"mdia", b"minf", b"stbl", b"edts", b"dinf", b"udta"}


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
        out.update(frames=float(len(frames)), frame_bytes_mean=float(frames.mean()),
                   frame_bytes_sd=float(frames.std()), frame_bytes_max=float(frames.max()),
                   frame_bytes_min=float(frames.min()), frame_bytes_first=float(frames[0]))
    return out


def png_features(data: bytes) -> dict[str, float]:
    out = {"poster_bytes": float(len(data))}
    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        width, height = struct.unpack(">II", data[16:24])
        out.update(poster_width=float(width), poster_height=float(height))
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


def clip_features(video: bytes, video_headers: dict, poster: bytes | None = None,
                  poster_headers: dict | None = None, motion: bytes | None = None,
                  motion_headers: dict | None = None) -> dict[str, float]:
    """Return every observable feature of one served clip (see the module docstring): its
    video, poster and, when the study plays in the page, the player's payload."""
    out = {"video_bytes": float(len(video)), **mp4_features(video),
           **header_features(video_headers, "video")}
    if poster is not None:
        out.update(png_features(poster))
        out.update(header_features(poster_headers or {}, "poster"))
    if motion is not None:
        out["motion_bytes"] = float(len(motion))
        out.update(header_features(motion_headers or {}, "motion"))
    return out


def _matrix(rows: list[dict]) -> np.ndarray:
    names = sorted({name for row in rows for name in row})
    x = np.array([[row.get(name, 0.0) for name in names] for row in rows], dtype=float)
    x[~np.isfinite(x)] = 0.0
    spread = x.std(axis=0)
    keep = spread > 1e-9 * (np.abs(x).max(axis=0) + 1.0)
    x = x[:, keep]
    return (x - x.mean(axis=0)) / (x.std(axis=0) if x.size else 1.0)


def _fit(x: np.ndarray, y: np.ndarray, l2: float = 1.0, steps: int = 50) -> np.ndarray:
    """Return weights (bias last) of an L2-regularised logistic regression (Newton steps)."""
    design = np.hstack([x, np.ones((len(x), 1))])
    w = np.zeros(design.shape[1])
    penalty = np.full(design.shape[1], l2)
    penalty[-1] = 0.0
    for _ in range(steps):
        p = 1 / (1 + np.exp(-np.clip(design @ w, -30, 30)))
        gradient = design.T @ (p - y) + penalty * w
        hessian = (design * (p * (1 - p))[:, None]).T @ design + np.diag(penalty + 1e-9)
        step = np.linalg.solve(hessian, gradient)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return w


def _folds(y: np.ndarray, k: int, rng) -> list[np.ndarray]:
    """Return ``k`` test-index folds, each with about the same share of both labels."""
    folds = [[] for _ in range(k)]
    for label in (0, 1):
        where = rng.permutation(np.flatnonzero(y == label))
        for i, index in enumerate(where):
            folds[i % k].append(index)
    return [np.asarray(sorted(f), dtype=int) for f in folds if f]


def audit(rows: list[dict], labels, folds: int = FOLDS, seed: int = 0) -> dict:
    """Return ``{"accuracy", "chance", "n", "margin", "passed"}`` of predicting ``labels``
    (booleans) from the clips' features ``rows`` with cross-validated logistic regression.

    Fewer than two clips of either label: nothing to tell apart, so ``passed`` with
    ``accuracy`` None.
    """
    y = np.asarray(labels, dtype=float)
    n = len(y)
    positives = int(y.sum())
    chance = max(positives, n - positives) / n if n else 1.0
    margin = max(MIN_MARGIN, Z * math.sqrt(chance * (1 - chance) / n)) if n else 0.0
    if min(positives, n - positives) < 2:
        return {"accuracy": None, "chance": chance, "n": n, "margin": margin, "passed": True}
    x = _matrix(rows)
    rng = np.random.default_rng(seed)
    right = 0
    for test in _folds(y, min(folds, min(positives, n - positives)), rng):
        train = np.setdiff1d(np.arange(n), test)
        w = _fit(x[train], y[train])
        guess = (np.hstack([x[test], np.ones((len(test), 1))]) @ w) > 0
        right += int((guess == (y[test] > 0.5)).sum())
    accuracy = right / n
    return {"accuracy": accuracy, "chance": chance, "n": n, "margin": margin,
            "passed": bool(accuracy <= chance + margin)}
