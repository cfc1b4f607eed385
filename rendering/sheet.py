"""A contact sheet of every clip in a folder: a few frames of each, labelled, side by side.

For researchers checking a stimulus set (that every clip keeps one framing and scale, that
nothing is cut off), never for participants: labels name sources. The folder may be one
``render`` output (``renders.json`` beside the clips), a stimulus build (``manifest.json``
and ``renders/``), the demo's build, or any folder of mp4s; clips are found recursively.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import imageio_ffmpeg
import numpy as np
from PIL import Image

from rendering.grid import GAP, PAPER, _band, _label_band


@dataclass(frozen=True)
class SheetClip:
    """One clip found in a folder, with what its records say about it."""

    video: Path
    label: str
    group: str


def _records(folder: Path) -> dict[str, dict]:
    """Return what ``renders.json`` and ``manifest.json`` files say per video hash."""
    known: dict[str, dict] = {}
    for record in sorted(folder.rglob("renders.json")):
        for clip in json.loads(record.read_text()).get("clips", []):
            known[Path(clip["video"]).stem] = clip
    for record in sorted(folder.rglob("manifest.json")):
        for clip in json.loads(record.read_text()).get("clips", []):
            if "video_hash" in clip:
                known.setdefault(clip["video_hash"], {}).update(clip)
    return known


def _listed_elsewhere(folder: Path, known: dict, found: set, cache: Path | None) -> list[Path]:
    """Return the videos a stimulus build's ``manifest.json`` under ``folder`` lists but
    ``folder`` does not hold: build_stimuli keeps them in its cache's ``renders/`` (by default
    ``<var>/stimuli/cache``, beside the study's build folder)."""
    listed = {h for h, record in known.items() if "motion_hash" in record} - found
    if not listed:
        return []
    places = [cache] if cache is not None else [folder.parent / "cache", folder.parent.parent / "cache"]
    out = []
    for place in places:
        for video_hash in sorted(listed):
            video = Path(place) / "renders" / f"{video_hash}.mp4"
            if video.is_file():
                out.append(video)
                listed.discard(video_hash)
    if listed and cache is not None:
        raise FileNotFoundError(f"{len(listed)} clips the manifest under {folder} lists are not "
                                f"in {Path(cache) / 'renders'}; pass the build's cache folder")
    return out


def find_clips(folder: str | Path, cache: str | Path | None = None) -> list[SheetClip]:
    """Return every mp4 under ``folder`` (temporary files skipped), and the clips a stimulus
    build's manifest there lists from its cache (``cache``, default the one beside it),
    labelled, in order."""
    folder = Path(folder)
    known = _records(folder)
    clips = []
    here = sorted(folder.rglob("*.mp4"))
    elsewhere = _listed_elsewhere(folder, known, {v.stem for v in here}, cache)
    for video in here + elsewhere:
        if video.name.startswith("."):
            continue
        record = known.get(video.stem, {})
        parts = [record.get("source"), record.get("action"), record.get("role")]
        if record.get("score") is not None:
            parts.append(f"score {record['score']}")
        label = " · ".join(str(p) for p in parts if p) or video.stem
        group = (str(video.parent.relative_to(folder)) if video.is_relative_to(folder)
                 and video.parent != folder else ".")
        clips.append(SheetClip(video, label, group))
    order = {"real": 0}
    clips.sort(key=lambda c: (c.group, order.get(c.label.split(" · ")[0], 1), c.label, c.video.name))
    return clips


def sample_frames(video: Path, moments: int, size: int) -> list[np.ndarray]:
    """Return ``moments`` frames of a video evenly spaced in time, resized to ``size``."""
    reader = imageio_ffmpeg.read_frames(str(video))
    meta = next(reader)
    width, height = meta["size"]
    frames = [np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader]
    if not frames:
        raise ValueError(f"{video}: no frames could be decoded")
    picks = np.linspace(0, len(frames) - 1, moments).round().astype(int)
    return [np.asarray(Image.fromarray(frames[k]).resize((size, size), Image.LANCZOS))
            for k in picks]


def write_sheet(folder: str | Path, out: str | Path, moments: int = 4, size: int = 96,
                columns: int = 3, cache: str | Path | None = None) -> Path:
    """Write a contact sheet of every clip under ``folder`` to ``out`` (PNG or JPEG).

    Each clip is a strip of ``moments`` frames of ``size`` pixels under its label; strips
    fill ``columns`` columns, group by group (each sub-folder is a group). A stimulus build's
    folder (its ``manifest.json``) takes its clips from the build's ``cache`` (see
    :func:`find_clips`).
    """
    clips = find_clips(folder, cache)
    if not clips:
        raise ValueError(f"no mp4 clips under {folder}")
    band = _band(size)
    strip_width = moments * (size + GAP) - GAP
    cells = []
    for group in dict.fromkeys(c.group for c in clips):
        members = [c for c in clips if c.group == group]
        # Each group opens a row of its own with its heading.
        cells.append(_label_band(f"{group}: {len(members)} clips", strip_width, band))
        cells.extend([None] * (columns - 1))
        for clip in members:
            strip = np.empty((band + size, strip_width, 3), np.uint8)
            strip[:] = PAPER
            strip[:band] = _label_band(clip.label, strip_width, band)
            for k, frame in enumerate(sample_frames(clip.video, moments, size)):
                left = k * (size + GAP)
                strip[band:, left:left + size] = frame
            cells.append(strip)
        cells.extend([None] * ((-len(cells)) % columns))
    rows = []
    for start in range(0, len(cells), columns):
        row_cells = cells[start:start + columns]
        height = max((c.shape[0] for c in row_cells if c is not None), default=band)
        row = np.empty((height + GAP, columns * (strip_width + 3 * GAP) - 3 * GAP, 3), np.uint8)
        row[:] = PAPER
        for k, cell in enumerate(row_cells):
            if cell is not None:
                left = k * (strip_width + 3 * GAP)
                row[:cell.shape[0], left:left + strip_width] = cell
        rows.append(row)
    sheet = Image.fromarray(np.concatenate(rows))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() in (".jpg", ".jpeg"):
        sheet.save(out, quality=85, optimize=True)
    else:
        sheet.save(out, optimize=True)
    return out
