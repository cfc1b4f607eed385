"""What every motion file format shares: its error type, the registry and small readers.

A format is a module with ``load(path, **options) -> list[Motion]`` (and ``save`` where
the format allows it), registered under a name with :func:`register_format`. Loaders
that read a folder return a :class:`MotionList`: the motions of the good files, and one
line per bad file in ``problems``, so good data in a batch is never lost.
"""

from __future__ import annotations

import csv
import re
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from motion import safe_load
from motion.motion import MotionError
from motion.registry import Registry
from motion.skeletons import get_skeleton


class FormatError(ValueError):
    """A motions file is missing, unreadable or not in the layout of its format."""


class MotionList(list):
    """Motions read from files, with ``problems`` (files skipped, and why) and ``notes``
    (what was found, e.g. the format ``auto`` detected)."""

    def __init__(self, motions: Iterable = (), problems=(), notes=()):
        super().__init__(motions)
        self.problems: list[str] = list(problems)
        self.notes: list[str] = list(notes)

    def absorb(self, other) -> "MotionList":
        """Add another load's motions, problems and notes to this one."""
        self.extend(other)
        self.problems.extend(getattr(other, "problems", []))
        self.notes.extend(getattr(other, "notes", []))
        return self


_FORMATS = Registry("motion format", package="motion.formats")


def register_format(name: str):
    """Return a decorator registering a format module (or object with ``load``) as ``name``."""
    return _FORMATS.register(name)


def format_module(module_name: str, name: str | None = None) -> None:
    """Register the format module called ``module_name`` (its ``__name__``, at its end) as
    ``name`` (default: the module's own name). Discovery imports every module of this
    package, so a new format is its module and no list names it."""
    _FORMATS.add(name or module_name.rsplit(".", 1)[-1], sys.modules[module_name])


def get_format(name: str):
    """Return a registered format by name (a module with ``load`` and maybe ``save``)."""
    try:
        return _FORMATS.get(name)
    except KeyError as exc:
        raise FormatError(exc.args[0]) from None


def list_formats() -> list[str]:
    """Return the names of every registered format (what a study config may name)."""
    return _FORMATS.names()


# --- readers -----------------------------------------------------------------------------


def read_npy(path: Path, what: str, objects: bool = False):
    """Return what a ``.npy`` file holds, or raise :class:`FormatError` naming the file.

    ``objects``: the file may hold Python objects (MDM's dicts); they are read as plain
    data only (:mod:`motion.safe_load`), never by running the file's pickle.
    """
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"{path} does not exist; expected a .npy file of {what}")
    if objects:
        try:
            return safe_load.load_npy(path)
        except safe_load.RefusedObject as exc:
            raise FormatError(str(exc)) from None
        except safe_load.DataFileError as exc:
            raise FormatError(f"{exc}; expected a .npy file of {what}") from None
    try:
        return np.load(path, allow_pickle=False)
    except ValueError as exc:
        if "allow_pickle" in str(exc):
            raise FormatError(f"{path} holds Python objects, not an array of {what}; is it "
                              "another format (e.g. mdm's results.npy)?") from None
        raise FormatError(f"{path} is not a readable .npy file of {what} ({exc})") from exc
    except Exception as exc:  # numpy raises several types for a damaged file
        raise FormatError(f"{path} is not a readable .npy file of {what} ({exc})") from exc


def read_npz(path: Path, what: str, objects: bool = False) -> dict:
    """Return the arrays of a ``.npz`` file by key, or raise :class:`FormatError`.

    ``objects``: members may hold Python objects, read as plain data only.
    """
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"{path} does not exist; expected a .npz file of {what}")
    if objects:
        try:
            return safe_load.load_npz(path)
        except safe_load.RefusedObject as exc:
            raise FormatError(str(exc)) from None
        except safe_load.DataFileError as exc:
            raise FormatError(f"{exc}; expected a .npz file of {what}") from None
    try:
        with np.load(path, allow_pickle=False) as data:
            return {key: data[key] for key in data.files}
    except Exception as exc:  # numpy raises many types for a broken zip
        raise FormatError(f"{path} is not a readable .npz file of {what} ({exc})") from exc


def pickled_dict(value, path: Path, what: str) -> dict:
    """Return the dict ``np.save`` stored as a 0-d object array, or raise naming the file."""
    if isinstance(value, np.ndarray) and value.dtype == object and value.shape == ():
        value = value.item()
    if not isinstance(value, dict):
        kind = getattr(value, "shape", type(value).__name__)
        raise FormatError(f"{path}: holds {kind}, not the dict of {what}")
    return value


def need_keys(data: dict, keys, path: Path, layout: str) -> None:
    """Raise :class:`FormatError` naming the keys of ``keys`` that ``data`` lacks."""
    missing = [key for key in keys if key not in data]
    if missing:
        raise FormatError(f"{path}: no key {', '.join(map(repr, missing))} (keys: "
                          f"{', '.join(map(repr, sorted(map(str, data)))) or 'none'}); "
                          f"expected {layout}")


def check_shape(array, expected: Callable[[tuple], bool], path: Path, key: str,
                layout: str) -> np.ndarray:
    """Return ``array`` as a float array if ``expected(shape)``, else raise naming the key."""
    array = np.asarray(array)
    if not np.issubdtype(array.dtype, np.number) or not expected(array.shape):
        raise FormatError(f"{path}: {key} has shape {array.shape} ({array.dtype}); "
                          f"expected {layout}")
    return array


def check_finite(array: np.ndarray, path: Path, key: str) -> None:
    """Raise :class:`FormatError` if ``array`` holds NaN or infinite values."""
    bad = ~np.isfinite(array)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise FormatError(f"{path}: {key} holds {int(bad.sum())} NaN or infinite values "
                          f"(first at index {where}); repair or drop that motion")


def finite_only(motions: list, path: Path) -> MotionList:
    """Return the motions whose joints (and vertices) are finite; the others are problems."""
    kept = MotionList()
    for index, motion in enumerate(motions):
        values = [motion.joints] + ([motion.vertices] if motion.has_body else [])
        bad = sum(int((~np.isfinite(v)).sum()) for v in values)
        if bad:
            kept.problems.append(f"{path}: motion {index} ({motion.text or motion.action}) has "
                                 f"{bad} NaN or infinite coordinates; skipped")
        else:
            kept.append(motion)
    if not kept:
        raise FormatError(f"{path}: every motion has NaN or infinite coordinates "
                          f"({len(motions)} motions)")
    return kept


def check_lengths(lengths, frames: int, count: int, path: Path, key: str = "lengths"):
    """Return lengths ``(N,)`` as ints in ``1..frames``, or raise naming the file."""
    lengths = np.asarray(lengths).reshape(-1)
    if lengths.shape != (count,) or not np.issubdtype(lengths.dtype, np.number):
        raise FormatError(f"{path}: {key} has shape {lengths.shape}; expected ({count},), one "
                          "per motion")
    if (lengths < 1).any() or (lengths > frames).any():
        bad = int(np.argmax((lengths < 1) | (lengths > frames)))
        raise FormatError(f"{path}: {key}[{bad}] is {int(lengths[bad])}, but the arrays hold "
                          f"{frames} frames; lengths must be in 1..{frames}")
    return lengths.astype(np.int64)


def skeleton_for(n_joints: int, name: str | None, path: Path, shape,
                 defaults: dict[int, str]) -> str:
    """Return ``name`` checked against ``n_joints``, else the format's default for that count."""
    if name is not None:
        try:
            skeleton = get_skeleton(name)
        except KeyError as exc:
            raise FormatError(exc.args[0]) from None
        if skeleton.dims != 3 or skeleton.n_joints != n_joints:
            raise FormatError(
                f"{path}: joints of shape {shape} hold {n_joints} joints per frame; skeleton "
                f"{name!r} has {skeleton.n_joints} joints in {skeleton.dims}D"
            )
        return name
    if n_joints not in defaults:
        known = ", ".join(f"{count} ({skeleton})" for count, skeleton in sorted(defaults.items()))
        raise FormatError(f"{path}: joints of shape {shape} hold {n_joints} joints per frame; "
                          f"this format knows {known}; pass skeleton")
    return defaults[n_joints]


def files_in(path: Path, patterns: tuple[str, ...], what: str) -> list[Path]:
    """Return the files matching ``patterns`` under a folder (recursively), sorted naturally."""
    path = Path(path)
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise FormatError(f"{path} does not exist; expected {what}")
    found = sorted({f for pattern in patterns for f in path.rglob(pattern) if f.is_file()},
                   key=natural_key)
    if not found:
        raise FormatError(f"{path}: no {' or '.join(patterns)} files; expected {what}")
    return found


def natural_key(path: Path):
    """Sort key putting ``sample2`` before ``sample10``."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", str(path))]


def load_each(files: list[Path], load_one: Callable[[Path], list], what: str) -> MotionList:
    """Load every file; bad ones go to ``problems`` by name. Raise if none loads."""
    result = MotionList()
    for path in files:
        try:
            result.absorb(load_one(path))
        except (FormatError, MotionError) as exc:
            message = str(exc)
            result.problems.append(message if str(path) in message else f"{path}: {message}")
    if not result and len(files) == 1:
        raise FormatError(result.problems[0])  # one file: its own error, naming it
    if not result:
        shown = "; ".join(result.problems[:3])
        more = f" (and {len(result.problems) - 3} more)" if len(result.problems) > 3 else ""
        raise FormatError(f"no {what} could be read: {shown}{more}")
    return result


# --- prompts -----------------------------------------------------------------------------

PROMPT_FILES = ("prompts.txt", "prompts.csv", "texts.txt", "texts.csv")


def read_prompts(path: Path) -> list[str] | dict[str, str]:
    """Return the prompts of a text file (one per line) or a CSV (``file``/``name`` and
    ``text``/``prompt``/``caption`` columns: a prompt per file name).

    A text line ``caption#...`` (HumanML3D's ``caption#tokens#start#end``, MoMask's
    ``caption#length``) keeps the part before the first ``#``; blank lines are skipped.
    """
    path = Path(path)
    if not path.is_file():
        raise FormatError(f"prompt file {path} does not exist; expected one prompt per line, "
                          "or a CSV with file and text columns")
    if path.suffix.lower() == ".csv":
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.DictReader(handle))
        if not rows:
            raise FormatError(f"{path}: the CSV has no rows")
        columns = {name.strip().lower(): name for name in rows[0]}
        key = next((columns[c] for c in ("file", "name", "id", "motion") if c in columns), None)
        text = next((columns[c] for c in ("text", "prompt", "caption") if c in columns), None)
        if text is None:
            raise FormatError(f"{path}: columns {', '.join(columns)}; expected a text (or "
                              "prompt, caption) column, and a file (or name) column")
        if key is None:
            return [row[text].strip() for row in rows]
        return {Path(row[key].strip()).stem: row[text].strip() for row in rows}
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    return [line.split("#", 1)[0].strip() for line in lines if line.strip()]


def prompt_file_beside(files: list[Path], root: Path) -> Path | None:
    """Return a prompt file in ``root`` (a folder) or beside the first file, if any."""
    folder = Path(root) if Path(root).is_dir() else Path(files[0]).parent
    return next((folder / name for name in PROMPT_FILES if (folder / name).is_file()), None)


_SAMPLE = re.compile(r"sample_?(\d+)", re.IGNORECASE)


def prompts_for(files: list[Path], prompts, source: Path) -> list[str]:
    """Return the prompt of each file: by name (CSV), by ``sample<k>`` in its name, or by order.

    Raise :class:`FormatError` when the prompts do not match the files.
    """
    if isinstance(prompts, dict):
        missing = [f.name for f in files if f.stem not in prompts]
        if missing:
            raise FormatError(f"{source}: no prompt for {', '.join(missing[:5])}"
                              f"{' ...' if len(missing) > 5 else ''}; the file column names "
                              f"{len(prompts)} files")
        return [prompts[f.stem] for f in files]
    samples = [_SAMPLE.search(f.stem) for f in files]
    if all(samples) and len(prompts) != len(files):
        indices = [int(m.group(1)) for m in samples]
        if max(indices) >= len(prompts):
            raise FormatError(f"{source}: {len(prompts)} prompts, but a file is named sample"
                              f"{max(indices)}; sample<k> takes line k+1 of the prompts")
        return [prompts[k] for k in indices]
    if len(prompts) != len(files):
        raise FormatError(f"{source}: {len(prompts)} prompts for {len(files)} motion files; "
                          "give one line per file in name order, or a CSV with file and text "
                          "columns")
    return list(prompts)


_WORD = re.compile(r"^[A-Za-z']+$")


def prompt_from_name(stem: str) -> str | None:
    """Return the prompt a file's name spells, as text-to-motion demos (T2M-GPT, MotionGPT)
    save it: ``a_person_is_boxing`` -> ``"a person is boxing"``; ``None`` for names that
    are not a sentence (fewer than three words, or any with digits: ``sample0_repeat1``)."""
    words = [word for word in re.split(r"[_\s]+", stem.strip()) if word]
    if len(words) < 3 or not all(_WORD.match(word) for word in words):
        return None
    return " ".join(words)
