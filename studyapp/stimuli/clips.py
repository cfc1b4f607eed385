"""Register rendered clips as the stimuli of a study.

Files are stored through Django's ``default_storage`` (``MEDIA_ROOT`` on the file
system, or an S3-compatible bucket: ``STUDY_S3_BUCKET``) as ``stimuli/<video_hash>.mp4``
(poster ``.png``): the name carries no source, and the same video registered twice is
stored once. Participants only ever see the stimulus token (see ``views.clip``).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from django.core.files import File
from django.core.files.storage import default_storage
from django.db import transaction

from studyapp.survey.models import Stimulus

HASH = re.compile(r"^[0-9a-f]{16,64}$")


@dataclass(frozen=True)
class Clip:
    """A rendered clip on its way into a study: what it shows and where its files are.

    ``role`` is a :class:`~studyapp.survey.models.Stimulus.Role` (``judged``, ``catch``,
    ``reference``, ``example``, ``anchor``, ``practice``); ``score`` is the score a
    scoring-standard example stands for; ``prompt`` the text the motion answers.
    """

    action: str
    source: str
    video: Path
    duration: float
    video_hash: str = ""
    motion_hash: str = ""
    poster: Path | None = None
    role: str = Stimulus.Role.JUDGED
    score: int | None = None
    prompt: str = ""
    motion: Path | None = None  # the in-browser player's payload (rendering.player)
    checkpoint: str = ""  # sha256 of the method checkpoint that made the motion
    training_seed: int | None = None  # that checkpoint's training seed

    @classmethod
    def rendered(cls, motion, rendered, **fields) -> "Clip":
        """Return the clip of ``motion`` as ``rendering.render_set`` reported it."""
        fields.setdefault("source", motion.source)
        return cls(action=motion.action, video=Path(rendered.video),
                   poster=Path(rendered.poster) if rendered.poster else None,
                   duration=rendered.duration, video_hash=rendered.video_hash,
                   motion_hash=rendered.motion_hash,
                   prompt=getattr(motion, "text", "") or "", **fields)


def file_hash(path) -> str:
    """Return the sha256 hex digest of a file."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


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


def register_clips(study, clips: Iterable[Clip]) -> list[Stimulus]:
    """Add rendered clips to a study and return their stimuli, in the order given.

    ``video_hash`` (sha256 of the mp4) is computed when missing. A clip whose video is
    already in the study returns the existing stimulus; the same video under another
    action, source or role is an error.
    """
    stimuli = []
    with transaction.atomic():
        for clip in clips:
            video = Path(clip.video)
            video_hash = str(clip.video_hash or file_hash(video)).lower()
            if not HASH.match(video_hash):
                raise ValueError(f"{video}: video_hash {video_hash!r} is not a hex digest")
            if not clip.action or not clip.source:
                raise ValueError(f"{video}: a clip needs an action and a source")
            if clip.role not in Stimulus.Role.values:
                raise ValueError(f"{video}: role {clip.role!r} is none of "
                                 f"{', '.join(Stimulus.Role.values)}")
            existing = Stimulus.objects.filter(study=study, video_hash=video_hash).first()
            if existing is not None:
                if (existing.action, existing.source, existing.role) != (
                        clip.action, clip.source, clip.role):
                    raise ValueError(
                        f"{video}: already in study {study.slug} as {existing.action}/"
                        f"{existing.source} ({existing.role}), not {clip.action}/{clip.source} "
                        f"({clip.role})"
                    )
                # The study now plays in the page, or its payload was made anew (another
                # payload version or framing: names are content hashes).
                if clip.motion and existing.motion != f"stimuli/{Path(clip.motion).name}":
                    existing.motion = _store(Path(clip.motion), Path(clip.motion).name)
                    existing.save(update_fields=["motion"])
                if clip.checkpoint and not existing.checkpoint:  # built before checkpoints were kept
                    existing.checkpoint, existing.training_seed = clip.checkpoint, clip.training_seed
                    existing.save(update_fields=["checkpoint", "training_seed"])
                stimuli.append(existing)
                continue
            stimuli.append(
                Stimulus.objects.create(
                    study=study,
                    action=clip.action,
                    prompt=clip.prompt,
                    source=clip.source,
                    role=clip.role,
                    video=_store(video, f"{video_hash}.mp4"),
                    poster=_store(Path(clip.poster), f"{video_hash}.png") if clip.poster else "",
                    motion=_store(Path(clip.motion), Path(clip.motion).name) if clip.motion else "",
                    duration=float(clip.duration),
                    motion_hash=clip.motion_hash,
                    video_hash=video_hash,
                    checkpoint=clip.checkpoint,
                    training_seed=clip.training_seed,
                )
            )
    return stimuli
