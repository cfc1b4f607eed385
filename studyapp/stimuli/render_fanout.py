"""A build's clips rendered by Celery workers on any number of machines
(``build_stimuli --workers celery``, or ``STUDY_RENDER_WORKERS=celery`` for build jobs).

Every machine mounts the build's cache folder at the same path (NFS, SMB, or one disk):
the clips come back into its ``renders/`` folder, named by their hash as a local build
names them. For each clip still to render the build

1. writes its motion to ``renders/.fanout/<key>.npz`` (``key``: the render cache's key of
   the clip, its motion hash and render settings) and queues one ``render_clip`` job on
   the ``render`` queue (``STUDY_RENDER_QUEUE``);
2. waits, counting the clips as their records ``renders/.fanout/<key>.json`` (video
   hash, duration) appear, whichever worker wrote them: the build's progress bar counts
   every worker's clips.

A worker (``celery -A studyapp worker -Q render``) holds a lease on the clip in Redis while
it draws (``SET ... EX``, renewed every third of ``STUDY_RENDER_LEASE`` seconds), writes
the files (under names of its own, then renamed to their hash), then the record, then
drops the lease. So it is idempotent and resumable:

- a clip whose record is there is done: a job delivered again returns it, and a build run
  again after its own process was killed takes what the workers finished meanwhile;
- a clip whose lease lapsed with no record lost its worker (killed, machine gone): the
  build queues it again; so too, when nothing has moved for ``STUDY_RENDER_STALL``
  seconds, every clip no worker has taken (a job lost with a worker before it started);
- two workers drawing one clip write the same bytes to the same names.

Registration stays with the build, after every clip is in: nothing is registered twice.
A clip that cannot be drawn is recorded as ``<key>.failed`` (the worker's host and
error) and reported as a local build reports it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import socket
import threading
import time
import uuid
from dataclasses import asdict
from pathlib import Path

from studyapp.survey.broker import broker_url

log = logging.getLogger(__name__)
# How a clip's job reaches the render workers: ``queue("render_clip", params)``. The app's
# ``ready`` sets it to Celery's, as it sets ``tasks.queue``; the job itself is
# ``tasks.render_clip``, which calls :func:`render_one`.
queue = None

FANOUT = ".fanout"  # beside the renders: motions to draw and the records of those drawn
LEASE_PREFIX = "study:render:lease:"
# Stall rounds (nothing taken, nothing finished) before the build gives up waiting.
MAX_STALLS = 3
# A worker's half-written file older than this is left by a killed worker: the next
# fanned-out build into the folder removes it (younger ones may still be being written).
STALE_FILES = 3600.0


class FanOutError(RuntimeError):
    """Fanned-out rendering cannot start or go on (no broker, no worker)."""


def _seconds(name: str, default: float) -> float:
    given = os.environ.get(name, "").strip()
    if not given:
        return default
    try:
        value = float(given)
    except ValueError:
        value = 0.0
    if not value > 0:
        raise FanOutError(f"{name}={given!r} is not a positive number of seconds; set it to "
                          f"e.g. {default:g}")
    return value


def lease_seconds() -> float:
    """How long a worker's lease on a clip lasts unless renewed (``STUDY_RENDER_LEASE``)."""
    return _seconds("STUDY_RENDER_LEASE", 30.0)


def stall_seconds() -> float:
    """How long nothing may move before untaken clips are queued again (``STUDY_RENDER_STALL``)."""
    return _seconds("STUDY_RENDER_STALL", 120.0)


def _redis():
    import redis

    url = broker_url()
    if not url.startswith(("redis://", "rediss://", "unix://")):
        raise FanOutError(f"rendering with Celery workers keeps its leases in the broker's "
                          f"Redis; STUDY_CELERY_BROKER is {url!r}: set it to "
                          f"redis://host:6379/0")
    return redis.Redis.from_url(url)


def lease_name(folder, key: str) -> str:
    """Return the Redis key of the lease on clip ``key`` of the renders folder ``folder``."""
    where = hashlib.sha256(str(Path(folder).resolve()).encode()).hexdigest()[:12]
    return f"{LEASE_PREFIX}{where}:{key}"


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}")
    tmp.write_text(text)
    os.replace(tmp, path)


def _read(path: Path):
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


# --- the worker's side -------------------------------------------------------------

def render_one(folder: str, key: str, style: str, size, framing: dict) -> dict:
    """Render the clip ``key`` queued in ``folder`` (a build's renders folder); return its
    record ``{"video_hash", "duration"}``. Done already: return the record, draw nothing."""
    from motion.formats import npz
    from rendering import Framing, render_clip

    folder = Path(folder)
    jobs = folder / FANOUT
    record_file = jobs / f"{key}.json"
    record = _read(record_file)
    if record is not None:
        return record
    motion_file = jobs / f"{key}.npz"
    me = f"{socket.gethostname()}:{os.getpid()}"
    if not motion_file.is_file():
        if not folder.is_dir():  # this machine does not see the build's folder
            raise FanOutError(f"render worker {me}: the build's renders folder {folder} is not "
                              f"here; mount the build's cache folder at the same path on every "
                              f"render machine")
        raise FanOutError(f"render worker {me}: {motion_file} is gone (its build finished or "
                          f"was cleaned); nothing to draw")
    client = _redis()
    lease = lease_seconds()
    held = lease_name(folder, key)
    client.set(held, me, ex=max(1, round(lease)))
    stop = threading.Event()

    def renew():
        while not stop.wait(lease / 3):
            client.set(held, me, ex=max(1, round(lease)))

    beat = threading.Thread(target=renew, name=f"lease-{key[:8]}", daemon=True)
    beat.start()
    try:
        [motion] = npz.load(motion_file)
        fields = dict(framing, target=tuple(framing["target"]))
        clip = render_clip(motion, folder, style, Framing(**fields), size)
        record = {"video_hash": clip.video_hash, "duration": clip.duration, "by": me}
        _write_atomic(record_file, json.dumps(record))
        return record
    except Exception as exc:
        _write_atomic(jobs / f"{key}.failed", f"{me}: {type(exc).__name__}: {exc}")
        raise
    finally:
        stop.set()
        beat.join()
        if client.get(held) == me.encode():
            client.delete(held)


# --- the build's side --------------------------------------------------------------

def fan_out(clips, folder, style: str, size, framing, on_clip=None, say=None, poll=0.2):
    """Render ``clips`` (``(key, motion)`` pairs) by Celery render workers into ``folder``.

    Return ``(records, failures)``: ``{key: {"video_hash", "duration"}}`` of every clip
    drawn and ``{key: message}`` of those that could not be. ``on_clip(key)`` is called
    once per clip as its record appears; ``say(message)`` tells what the build waits for.
    """
    from motion.formats import npz

    say = say or log.info
    if not broker_url():
        raise FanOutError("--workers celery sends clips to Celery render workers: set "
                          "STUDY_CELERY_BROKER=redis://host:6379/0 here and on the workers, and "
                          "start them with `celery -A studyapp worker -Q render` "
                          "(docs/PRODUCTION.md), or build without --workers celery")
    if queue is None:
        raise FanOutError("STUDY_CELERY_BROKER is set but no queue is: run inside the Django "
                          "app (its ready() sets render_fanout.queue)")
    client = _redis()
    folder = Path(folder)
    jobs = folder / FANOUT
    jobs.mkdir(parents=True, exist_ok=True)
    for left in folder.glob(".rendering-*"):  # half-written files of workers killed long ago
        try:
            if time.time() - left.stat().st_mtime > STALE_FILES:
                left.unlink()
        except FileNotFoundError:
            pass
    job = {"folder": str(folder.resolve()), "style": style, "size": size,
           "framing": asdict(framing)}
    records, failures, pending = {}, {}, {}
    for key, motion in clips:
        if key in records or key in pending:
            continue
        record = _read(jobs / f"{key}.json")
        if record is not None:  # a worker drew it for an earlier run of this build
            records[key] = record
            if on_clip:
                on_clip(key)
            continue
        (jobs / f"{key}.failed").unlink(missing_ok=True)
        tmp = jobs / f".{key}.{uuid.uuid4().hex[:12]}.npz"
        npz.save(tmp, [motion])
        os.replace(tmp, jobs / f"{key}.npz")
        pending[key] = False  # taken by a worker yet (a lease seen)?

    def send(keys):
        for key in keys:
            queue("render_clip", {"key": key, **job})

    send(list(pending))
    if pending:
        say(f"queued {len(pending)} clips for Celery render workers "
            f"(queue {os.environ.get('STUDY_RENDER_QUEUE', 'render')})")
    stall, moved, stalls = stall_seconds(), time.monotonic(), 0
    while pending:
        time.sleep(poll)
        keys = list(pending)
        with client.pipeline(transaction=False) as pipe:
            for key in keys:
                pipe.exists(lease_name(folder, key))
            leased = pipe.execute()
        for key, held in zip(keys, leased):
            record = _read(jobs / f"{key}.json")
            if record is not None:
                records[key] = record
                del pending[key]
                moved, stalls = time.monotonic(), 0
                if on_clip:
                    on_clip(key)
            elif (jobs / f"{key}.failed").is_file():
                failures[key] = (jobs / f"{key}.failed").read_text()
                del pending[key]
                moved = time.monotonic()
            elif held:
                pending[key] = True
                moved = time.monotonic()
            elif pending[key]:  # its worker held it and is gone, without a record
                say(f"clip {key[:12]}: its render worker stopped; queued again")
                pending[key] = False
                send([key])
                moved = time.monotonic()
        if pending and time.monotonic() - moved > stall:
            untaken = [key for key, taken in pending.items() if not taken]
            stalls += 1
            if stalls > MAX_STALLS:
                raise FanOutError(
                    f"no render worker took or finished a clip in {stall * stalls:.0f} s "
                    f"({len(pending)} left); start workers with `celery -A studyapp worker -Q "
                    f"render` on machines that mount {folder.parent} at the same path, or build "
                    f"without --workers celery")
            say(f"nothing moved in {stall:.0f} s: {len(untaken)} clips queued again; is a "
                f"render worker running (celery -A studyapp worker -Q render)?")
            send(untaken)
            moved = time.monotonic()
    return records, failures


def clean(folder, keys) -> None:
    """Remove the queued motions and records of ``keys`` (once the build's index has them)."""
    jobs = Path(folder) / FANOUT
    for key in keys:
        for suffix in (".npz", ".json", ".failed"):
            (jobs / f"{key}{suffix}").unlink(missing_ok=True)
