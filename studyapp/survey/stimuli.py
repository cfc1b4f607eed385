"""Register rendered clips as the stimuli of a study.

Files are copied to ``MEDIA_ROOT/stimuli/<video_hash>.mp4`` (poster ``.png``): the name
carries no source, and the same video registered twice is stored once. Participants
only ever see the stimulus token (see ``views.clip``).
"""

import hashlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

from django.conf import settings
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


def _store(src: Path, name: str) -> str:
    """Copy ``src`` to ``MEDIA_ROOT/stimuli/name`` once; return the relative path."""
    relative = f"stimuli/{name}"
    dst = Path(settings.MEDIA_ROOT) / relative
    if dst.is_file() and dst.stat().st_size == src.stat().st_size:
        return relative
    dst.parent.mkdir(parents=True, exist_ok=True)
    # Copy beside the target, then rename: a half-written file is never served.
    fd, tmp = tempfile.mkstemp(dir=dst.parent, prefix=".incoming-")
    try:
        with os.fdopen(fd, "wb") as out, open(src, "rb") as f:
            shutil.copyfileobj(f, out)
        os.replace(tmp, dst)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
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
