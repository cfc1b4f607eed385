"""Register rendered clips as the stimuli of a study.

Files are stored through Django's ``default_storage`` (``MEDIA_ROOT`` on the file
system, or an S3-compatible bucket: ``STUDY_S3_BUCKET``) as ``stimuli/<video_hash>.mp4``
(poster ``.png``): the name carries no source, and the same video registered twice is
stored once. Participants only ever see the stimulus token (see ``views.clip``).
"""

import hashlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

from django.core.files import File
from django.core.files.storage import default_storage
from django.db import transaction

from studyapp.survey.models import Stimulus

HASH = re.compile(r"^[0-9a-f]{16,64}$")
FLAGS = ("is_catch", "is_reference", "is_standard_example")


def file_hash(path) -> str:
    """Return the sha256 hex digest of a file."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _read(clip, *names, default=None):
    """Return the first of ``names`` a mapping or object has."""
    for name in names:
        value = clip.get(name) if isinstance(clip, Mapping) else getattr(clip, name, None)
        if value is not None:
            return value
    return default


class _Staged(File):
    """A complete copy beside the target, which FileSystemStorage renames into place."""

    def temporary_file_path(self):
        return self.file.name


def _save(relative: str, src: Path) -> str:
    """Save ``src`` as ``relative`` in ``default_storage``; return the name it chose."""
    try:
        target = Path(default_storage.path(relative))
    except NotImplementedError:  # object storage: an upload appears whole when done
        with open(src, "rb") as f:
            return default_storage.save(relative, File(f, name=relative))
    # Copy beside the target, then let the storage rename it: a half-written file is
    # never served.
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=".incoming-")
    try:
        with os.fdopen(fd, "wb") as out, open(src, "rb") as f:
            shutil.copyfileobj(f, out)
        with open(tmp, "rb") as f:
            return default_storage.save(relative, _Staged(f, name=relative))
    finally:
        Path(tmp).unlink(missing_ok=True)


def _store(src: Path, name: str) -> str:
    """Store ``src`` as ``stimuli/name`` in ``default_storage`` once; return that name.

    ``name`` is the content hash, so a stored file of the same size is this file and
    is not uploaded again. The name is never changed: a storage that would save under
    another name (the name was taken meanwhile by the same file) has that copy removed.
    """
    relative = f"stimuli/{name}"
    size = Path(src).stat().st_size
    if default_storage.exists(relative):
        if default_storage.size(relative) == size:
            return relative
        default_storage.delete(relative)  # a broken copy: store it again
    saved = _save(relative, Path(src))
    if saved != relative:
        default_storage.delete(saved)
        if not (default_storage.exists(relative) and default_storage.size(relative) == size):
            raise RuntimeError(f"the storage saved {relative} as {saved}")
    return relative


def register_clips(study, clips: Iterable) -> list[Stimulus]:
    """Add rendered clips to a study and return their stimuli, in the order given.

    Each clip is a mapping or object with ``action``, ``source``, ``video`` (or
    ``video_path``: an mp4 anywhere on disk), optional ``poster`` (or ``poster_path``:
    a png), ``duration`` in seconds, ``motion_hash`` and ``video_hash`` (sha256 of the
    mp4; computed when missing) and the optional flags ``is_catch``, ``is_reference``
    and ``is_standard_example``. A clip whose video is already in the study returns
    the existing stimulus; the same video under another action or source is an error.
    """
    stimuli = []
    with transaction.atomic():
        for clip in clips:
            video = Path(_read(clip, "video", "video_path"))
            poster = _read(clip, "poster", "poster_path")
            video_hash = str(_read(clip, "video_hash", default="") or file_hash(video)).lower()
            if not HASH.match(video_hash):
                raise ValueError(f"{video}: video_hash {video_hash!r} is not a hex digest")
            action, source = _read(clip, "action"), _read(clip, "source")
            if not action or not source:
                raise ValueError(f"{video}: a clip needs an action and a source")
            existing = Stimulus.objects.filter(study=study, video_hash=video_hash).first()
            if existing is not None:
                if (existing.action, existing.source) != (action, source):
                    raise ValueError(
                        f"{video}: already in study {study.slug} as "
                        f"{existing.action}/{existing.source}, not {action}/{source}"
                    )
                stimuli.append(existing)
                continue
            stimuli.append(
                Stimulus.objects.create(
                    study=study,
                    action=action,
                    source=source,
                    video=_store(video, f"{video_hash}.mp4"),
                    poster=_store(Path(poster), f"{video_hash}.png") if poster else "",
                    duration=float(_read(clip, "duration")),
                    motion_hash=str(_read(clip, "motion_hash", default="")),
                    video_hash=video_hash,
                    **{flag: bool(_read(clip, flag, default=False)) for flag in FLAGS},
                )
            )
    return stimuli
