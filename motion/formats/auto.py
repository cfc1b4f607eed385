"""Detect the format of each file from its content, then read it with that format.

Every format module has ``detect(probe)`` (see :mod:`motion.formats.probe`): the
reason it recognises a file or folder, or ``None``. A file is the format whose detector
recognises it; a folder is first offered whole (HumanML3D's ``new_joints/`` and
``new_joint_vecs/`` layouts), else every motion file under it (``.npy``, ``.npz``,
``.bvh``, ``.pkl``, ``.joblib``, ...) is detected alone and the files grouped by format.
A folder of one format is read by that format as a folder (prompt files beside it work
as they do there); a mixed folder is read file by file. Every group that reads is
kept; the result's ``problems`` name each file skipped and why, its ``notes`` what was
found (a table of format, skeleton, frame rate and count).

``options`` go to each format that takes them; the others are ignored.
"""

from __future__ import annotations

import inspect
from collections import Counter
from pathlib import Path

from motion.formats.base import (
    FormatError,
    MotionList,
    format_module,
    get_format,
    list_formats,
    natural_key,
)
from motion.formats.probe import SUFFIXES, Probe
from motion.motion import Motion, MotionError

IGNORED_STEMS = ("Mean", "Std")  # HumanML3D's normalisation arrays beside its features


def detectors() -> dict[str, object]:
    """Return every format's detector by format name (``auto`` has none of its own)."""
    return {name: get_format(name).detect for name in list_formats()
            if name != "auto" and hasattr(get_format(name), "detect")}


def suffixes() -> tuple[str, ...]:
    """Return the file endings of motion files: the common ones and those a format module
    declares it reads (its ``SUFFIXES``)."""
    declared = {suffix.lower() for name in list_formats()
                for suffix in getattr(get_format(name), "SUFFIXES", ())}
    return tuple(sorted(set(SUFFIXES) | declared))


def detect(path: str | Path, options: dict | None = None) -> tuple[str, str]:
    """Return ``(format, why)`` for one file (or a folder some format reads whole), or
    raise :class:`FormatError` saying what was seen."""
    path = Path(path)
    if not path.exists():
        raise FormatError(f"{path} does not exist")
    probe = Probe(path, options)
    found = [(name, why) for name, detector in detectors().items()
             if (why := detector(probe)) is not None]
    if found:
        return found[0]
    if path.is_dir():
        raise FormatError(f"{path}: no format reads this folder whole")
    if probe.suffix not in suffixes():
        raise FormatError(f"{path}: cannot tell the format of a {probe.suffix or 'suffix-less'} "
                          f"file (motion files end in {', '.join(suffixes())}); pass --format")
    raise FormatError(f"{path}: {_seen(probe)}, which no format has; pass --format")


def _seen(probe: Probe) -> str:
    """Say what a file holds, for an error."""
    if probe.shape is not None:
        return f"an array of shape {probe.shape}"
    if probe.keys:
        return (f"a {probe.suffix} file with keys {', '.join(sorted(probe.keys)[:12])}"
                f"{' ...' if len(probe.keys) > 12 else ''}")
    content = probe.content
    kind = type(content).__name__
    if isinstance(content, (list, tuple)) and content:
        kind += f" of {len(content)} {type(content[0]).__name__}"
    return f"a {probe.suffix} file holding {kind}"


def survey(folder: Path, options: dict | None = None):
    """Return the motion files under a folder grouped by format ``{format: [(file, why)]}``
    and the files no format recognised ``[(file, reason)]``."""
    endings = suffixes()
    files = sorted((f for f in Path(folder).rglob("*") if f.is_file()
                    and f.suffix.lower() in endings and f.stem not in IGNORED_STEMS),
                   key=natural_key)
    if not files:
        raise FormatError(f"{folder}: no motion files ({', '.join(endings)}) to detect a "
                          "format from")
    groups: dict[str, list[tuple[Path, str]]] = {}
    skipped = []
    for file in files:
        try:
            fmt, why = detect(file, options)
        except FormatError as exc:
            skipped.append((file, str(exc)))
            continue
        groups.setdefault(fmt, []).append((file, why))
    return groups, skipped


def _read(fmt: str, path: Path, options: dict):
    module = get_format(fmt)
    accepted = set(inspect.signature(module.load).parameters)
    return module.load(path, **{k: v for k, v in options.items() if k in accepted})


def load(path: str | Path, **options) -> list[Motion]:
    """Detect each file's format (see the module docstring) and read every group."""
    path = Path(path)
    if path.is_file() or not path.exists():
        fmt, why = detect(path, options)
        loaded = _read(fmt, path, options)
        result = MotionList(problems=getattr(loaded, "problems", ()),
                            notes=[f"{path}: detected format {fmt!r} ({why})"])
        result.extend(loaded)
        result.notes.extend(getattr(loaded, "notes", ()))
        return result
    whole = [(name, why) for name, detector in detectors().items()
             if (why := detector(Probe(path, options))) is not None]
    if whole:
        fmt, why = whole[0]
        result = MotionList(notes=[f"{path}: detected format {fmt!r} ({why})"])
        return result.absorb(_read(fmt, path, options))
    groups, skipped = survey(path, options)
    result = MotionList(problems=[message if str(file) in message else f"{file}: {message}"
                                  for file, message in skipped])
    table = []
    for fmt, members in groups.items():
        files = [file for file, _ in members]
        one_kind = len(groups) == 1 and not skipped
        result.notes.append(f"{path}: detected format {fmt!r} for {len(files)} file"
                            f"{'s' if len(files) > 1 else ''} ({members[0][1]}, e.g. "
                            f"{files[0].name})")
        group = MotionList()
        if one_kind:
            try:
                group.absorb(_read(fmt, path, options))
            except (FormatError, MotionError) as exc:
                group.problems.append(f"{path} as {fmt}: {exc}")
        else:
            for file in files:
                try:
                    group.absorb(_read(fmt, file, options))
                except (FormatError, MotionError) as exc:
                    message = str(exc)
                    group.problems.append(message if str(file) in message
                                          else f"{file}: {message}")
        result.absorb(group)
        counts = Counter((motion.skeleton, motion.fps) for motion in group)
        table += [(fmt, skeleton, fps, count) for (skeleton, fps), count in counts.items()]
    if table:
        result.notes.append(format_table(path, table))
    if not result:
        shown = "; ".join(result.problems[:3])
        raise FormatError(f"{path}: no motions could be read: {shown}"
                          f"{' ...' if len(result.problems) > 3 else ''}")
    return result


def format_table(path: Path, rows) -> str:
    """Return the table of what a folder held: format, skeleton, fps, count."""
    header = ("format", "skeleton", "fps", "motions")
    cells = [header] + [(fmt, skeleton, f"{fps:g}", str(count)) for fmt, skeleton, fps, count
                        in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(4)]
    lines = [f"{path}: found"] + ["  " + "  ".join(cell.ljust(width) for cell, width
                                                  in zip(row, widths)).rstrip()
                                  for row in cells]
    return "\n".join(lines)


format_module(__name__)
