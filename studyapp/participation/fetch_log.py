"""The record that a clip was sent to its last byte, kept first where no lock holds it up.

The clip view learns that a delivery's last byte is being handed to the server
(``media.file_response``'s ``on_sent``, called just before the last chunk goes out, and
told afterwards whether the server took it). That fact decides whether an answer is
taken (:meth:`studyapp.participation.flow.DatabaseStore.watch_problems`), so it must be on record
before the participant can answer, and a database write is not: on SQLite every write
queues for the one write lock, and under load the queue is longer than a clip plays.
So :func:`note` first writes the fact as a *witness* that no database lock holds up:

- with ``STUDY_FETCH_LOG_URL`` (default: ``STUDY_CACHE_URL``) set to Redis, a list per
  item token in Redis (one round trip; it outlives the worker that wrote it). Nothing
  is written to the database then: the witnesses are folded into ``TrialItem.fetched``
  and ``fetched_at`` in one statement when the trial is answered (the answer needs
  them) and every ``STUDY_FETCH_FLUSH_S`` seconds by a thread of each worker (or
  ``manage.py flush_fetches``);
- otherwise a small append-only file per item token under ``STUDY_FETCH_SPOOL`` (on this
  machine; it outlives the process too), followed by the database write as before,
  except that on SQLite it waits at most ``STUDY_FETCH_WRITE_WAIT_S`` (0.05 s) for the
  write lock: under load the write is left to the answer and to a flushing thread. The
  file is dropped once the write is done, so it only holds what the database has not
  caught up with yet.

An answer's check reads the database *and* the witnesses: a clip counts as fetched
whole when its byte ranges, from both, cover the file. A witness exists only after the
server sent the last byte, under a token the clip view looked up; a bot that skips the
fetch has none and is refused as before. Folding is idempotent (byte ranges merge), so
a witness that is read twice, or folded by two workers, does no harm; it is removed only
after the transaction that folded it committed.

A witness is written before the last chunk is handed over, so neither the database nor
this thread's wait to run again (dozens of threads share one interpreter) can put it
behind the participant's answer; when the server does not take that chunk (the client
went away) it is withdrawn.

A witness line is ``ext start end size time nonce``: the file's byte range sent (inclusive),
its size, and when the last byte went (Unix seconds).
"""

from __future__ import annotations

import fcntl
import logging
import os
import re
import secrets
import threading
import time
from contextlib import contextmanager
from datetime import datetime, timezone as dt_timezone
from pathlib import Path

from django.conf import settings
from django.db import DatabaseError, close_old_connections, connection, transaction

from studyapp.stimuli.media import merge_ranges
from studyapp.survey.models import TrialItem

log = logging.getLogger(__name__)

TOKEN = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
EXTS = ("mp4", "motion")
STALE_S = 7 * 24 * 3600  # witnesses of tokens no longer in the database are dropped after this
REDIS_TTL_S = 30 * 24 * 3600
BATCH = 100  # items folded per statement by flush()


# --- witness lines ------------------------------------------------------------------


def make_line(ext: str, start: int, end: int, size: int, at: float | None = None) -> str:
    at = time.time() if at is None else at
    return f"{ext} {int(start)} {int(end)} {int(size)} {at:.6f} {secrets.token_hex(4)}"


def parse_line(line: str):
    """Return ``(ext, start, end, size, at)`` of a witness line, or None (a torn line)."""
    parts = line.split()
    if len(parts) != 6 or parts[0] not in EXTS:
        return None
    try:
        start, end, size, at = int(parts[1]), int(parts[2]), int(parts[3]), float(parts[4])
    except ValueError:
        return None
    if not 0 <= start <= end < size:
        return None
    return parts[0], start, end, size, at


def fold(fetched, fetched_at, lines):
    """Return ``(fetched, fetched_at, changed)``: an item's recorded byte ranges and
    completion time with the witness ``lines`` merged in (in the order they were sent).

    As ``TrialItemManager.record_fetch``: an item is fetched whole the first time the
    ranges of one of its files cover that file; that time is the witness's own.
    """
    fetched = dict(fetched) if isinstance(fetched, dict) else {}
    changed = False
    entries = sorted(filter(None, map(parse_line, lines)), key=lambda e: e[4])
    for ext, start, end, size, at in entries:
        if fetched_at is not None:
            break  # as record_fetch: once whole, the ranges stay as they were
        ranges = merge_ranges([*fetched.get(ext, []), [start, end]])
        if ranges != fetched.get(ext):
            fetched[ext] = ranges
            changed = True
        if ranges == [[0, size - 1]]:
            fetched_at = datetime.fromtimestamp(at, tz=dt_timezone.utc)
            changed = True
    return fetched, fetched_at, changed


# --- where witnesses are kept ----------------------------------------------------------


class SpoolLog:
    """One append-only file per item token in a folder of this machine.

    Appends take the file's ``flock`` (held for one ``write``); a removal takes it too and
    either rewrites the file in place or unlinks it; an appender that finds the file it
    locked unlinked opens it anew.
    """

    writes_database = True

    def __init__(self, folder):
        self.folder = Path(folder)

    def path(self, token: str) -> Path:
        return self.folder / token

    def append(self, token: str, line: str) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self.path(token)
        data = (line + "\n").encode()
        while True:
            fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX)
                try:
                    same = os.stat(path).st_ino == os.fstat(fd).st_ino
                except FileNotFoundError:
                    same = False
                if same:
                    os.write(fd, data)
                    return
            finally:
                os.close(fd)

    def read(self, tokens) -> dict[str, list[str]]:
        out = {}
        for token in tokens:
            try:
                text = self.path(token).read_text()
            except OSError:  # none (the usual case), or no spool folder at all
                continue
            lines = [line for line in text.split("\n") if line]
            if lines:
                out[token] = lines
        return out

    def remove(self, token: str, lines) -> None:
        path = self.path(token)
        try:
            fd = os.open(path, os.O_RDWR)
        except FileNotFoundError:
            return
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            try:
                if os.stat(path).st_ino != os.fstat(fd).st_ino:
                    return
            except FileNotFoundError:
                return
            done = set(lines)
            text = os.pread(fd, os.fstat(fd).st_size, 0).decode(errors="replace")
            left = [line for line in text.split("\n") if line and line not in done]
            if not left:
                os.unlink(path)
            else:
                data = ("\n".join(left) + "\n").encode()
                os.ftruncate(fd, 0)
                os.pwrite(fd, data, 0)
        finally:
            os.close(fd)

    def tokens(self) -> list[str]:
        try:
            return [p.name for p in self.folder.iterdir() if TOKEN.match(p.name)]
        except OSError:
            return []


# Removes the given lines from a token's list and, when it is empty, the token from the
# set of tokens with witnesses: in one step, so an append in between is never orphaned.
_REMOVE = """
for i = 3, #ARGV do redis.call('LREM', KEYS[1], 1, ARGV[i]) end
if redis.call('LLEN', KEYS[1]) == 0 then redis.call('SREM', KEYS[2], ARGV[1]) end
return 1
"""


class RedisLog:
    """A list per item token in Redis, and a set of the tokens that have one."""

    writes_database = False

    def __init__(self, url: str, prefix: str = "study:fetch:", timeout: float = 0.25):
        import redis

        self.client = redis.Redis.from_url(url, socket_timeout=max(timeout, 0.5),
                                           socket_connect_timeout=max(timeout, 0.5))
        self.prefix = prefix
        self.dirty = prefix + "tokens"
        self._remove = self.client.register_script(_REMOVE)

    def key(self, token: str) -> str:
        return self.prefix + "t:" + token

    def append(self, token: str, line: str) -> None:
        pipe = self.client.pipeline(transaction=True)
        pipe.rpush(self.key(token), line)
        pipe.expire(self.key(token), REDIS_TTL_S)
        pipe.sadd(self.dirty, token)
        pipe.execute()

    def read(self, tokens) -> dict[str, list[str]]:
        tokens = list(tokens)
        if not tokens:
            return {}
        pipe = self.client.pipeline(transaction=False)
        for token in tokens:
            pipe.lrange(self.key(token), 0, -1)
        out = {}
        for token, lines in zip(tokens, pipe.execute()):
            if lines:
                out[token] = [line.decode() for line in lines]
        return out

    def remove(self, token: str, lines) -> None:
        self._remove(keys=[self.key(token), self.dirty], args=[token, "", *lines])

    def tokens(self) -> list[str]:
        return [t.decode() for t in self.client.sscan_iter(self.dirty, count=1000)
                if TOKEN.match(t.decode())]


_backend = None
_backend_for = None
_lock = threading.Lock()


def backend():
    """Return the witness store these settings name (built once per process)."""
    global _backend, _backend_for
    url = getattr(settings, "STUDY_FETCH_LOG_URL", "")
    spool = str(getattr(settings, "STUDY_FETCH_SPOOL", Path(settings.VAR_DIR) / "fetches"))
    prefix = getattr(settings, "STUDY_FETCH_LOG_PREFIX", "study:fetch:")
    wanted = (url, spool, prefix)
    with _lock:
        if _backend_for != wanted:
            _backend = (RedisLog(url, prefix, getattr(settings, "CACHE_TIMEOUT_S", 0.25))
                        if url else SpoolLog(spool))
            _backend_for = wanted
        return _backend


def spool():
    return SpoolLog(getattr(settings, "STUDY_FETCH_SPOOL", Path(settings.VAR_DIR) / "fetches"))


# --- the clip view's side ----------------------------------------------------------------


def note(item_pk: int, token: str, ext: str, start: int, end: int, size: int):
    """Record that bytes ``start..end`` of an item's ``ext`` file are being sent: called
    as the last chunk goes to the server (``media.file_response``'s ``on_sent``).

    The witness is written now (Redis, or the spool file when there is no Redis or it
    does not answer); return what to do once the server took that chunk (``done``:
    with the spool, the database write, then the witness is dropped) or did not
    (``undo``: the client went away, the witness is withdrawn).
    """
    if not TOKEN.match(token):
        return None
    line = make_line(ext, start, end, size)
    store = backend()
    try:
        store.append(token, line)
    except Exception as error:  # Redis down or hung: this machine's spool instead
        log.warning("fetch witness of %s not in %s (%s): the spool and the database instead",
                    token, type(store).__name__, error)
        store = spool()
        try:
            store.append(token, line)
        except OSError as error:  # no writable spool either: the database write alone
            log.warning("fetch witness of %s not in the spool (%s)", token, error)
            store = None
    return _Sending(store, item_pk, token, line, (ext, start, end, size))


class _Sending:
    def __init__(self, store, item_pk, token, line, fetch):
        self.store, self.item_pk, self.token, self.line, self.fetch = (
            store, item_pk, token, line, fetch)

    def done(self) -> None:
        if self.store is not None and not self.store.writes_database:
            start_flusher()
            return
        if self.store is None:  # no witness: the write must wait its turn
            TrialItem.objects.record_fetch(self.item_pk, *self.fetch)
            return
        try:
            with waiting_at_most(getattr(settings, "STUDY_FETCH_WRITE_WAIT_S", 0.05)):
                TrialItem.objects.record_fetch(self.item_pk, *self.fetch)
        except DatabaseError as error:
            log.warning("fetch of item %s not written yet (%s): its witness stands in for it",
                        self.item_pk, error)
            start_flusher()  # the witness reaches the database without an answer too
            return
        self.store.remove(self.token, [self.line])

    def undo(self) -> None:
        if self.store is None:
            return
        try:
            self.store.remove(self.token, [self.line])
        except Exception as error:
            log.warning("fetch witness of %s not withdrawn: %s", self.token, error)


@contextmanager
def waiting_at_most(seconds: float):
    """On SQLite, wait at most ``seconds`` for the write lock (not the connection's 30 s):
    a fetch whose witness is written need not queue behind every participant's answer,
    and its place in the queue is what holds the answers up. Elsewhere, do nothing."""
    if connection.vendor != "sqlite" or connection.in_atomic_block:
        yield
        return
    connection.ensure_connection()
    with connection.cursor() as cursor:
        before = cursor.execute("PRAGMA busy_timeout").fetchone()[0]
        cursor.execute(f"PRAGMA busy_timeout = {max(0, int(seconds * 1000))}")
    try:
        yield
    finally:
        with connection.cursor() as cursor:
            cursor.execute(f"PRAGMA busy_timeout = {int(before)}")


# --- the answer's side -------------------------------------------------------------------


def witness(items) -> list:
    """Fold the witnesses of ``items`` whose ``fetched_at`` is not set into them, in
    memory; return the items that changed (:func:`merged` locks and merges them for the
    answer's own write, :func:`settle` writes them alone)."""
    waiting = {item.token: item for item in items if item.fetched_at is None}
    if not waiting:
        return []
    found = {}
    for store in _stores():
        try:
            for token, lines in store.read(waiting).items():
                found.setdefault(token, []).extend(lines)
        except Exception as error:
            log.warning("fetch witnesses not read from %s: %s", type(store).__name__, error)
    if set(found) != set(waiting):
        # A witness is dropped only after its database write committed: read again
        # what the database has of the items whose witness was not found.
        missing = [item for token, item in waiting.items() if token not in found]
        rows = dict(TrialItem.objects.filter(pk__in=[i.pk for i in missing])
                    .values_list("pk", "fetched_at"))
        for item in missing:
            item.fetched_at = item.fetched_at or rows.get(item.pk)
    changed = []
    for token, lines in found.items():
        item = waiting[token]
        item.fetched, item.fetched_at, did = fold(item.fetched, item.fetched_at, lines)
        item._fetch_witnesses = lines
        if did:
            changed.append(item)
    return changed


def merged(items) -> bool:
    """Under the rows' locks, merge the witnesses :func:`witness` folded into ``items``
    with what was committed meanwhile (a queued ``record_fetch``), so nothing committed
    is written over: every item's ``fetched`` and ``fetched_at`` are then what to write.
    Return False (nothing read, nothing locked) when no item had a witness. The
    witnesses are dropped once the caller's transaction commits."""
    read = [item for item in items if getattr(item, "_fetch_witnesses", None)]
    if not read:
        return False
    current = TrialItem.objects.lock_fetches(items)
    for item in items:
        fetched, at = current.get(item.pk, (item.fetched, item.fetched_at))
        lines = getattr(item, "_fetch_witnesses", None)
        if lines:
            fetched, at, _ = fold(fetched, at, lines)
        item.fetched, item.fetched_at = fetched, at
    done = [(item.token, item._fetch_witnesses) for item in read]
    transaction.on_commit(lambda: _drop(done))
    return True


def settle(items) -> None:
    """Write what :func:`witness` folded into ``items`` (inside the caller's transaction;
    an answer writes them with its own, ``TrialManager.record_answer(fetches=merged)``)."""
    if merged(items):
        TrialItem.objects.bulk_update(items, ["fetched", "fetched_at"])


def _stores():
    store = backend()
    return [store] if isinstance(store, SpoolLog) else [store, spool()]


def _drop(done) -> None:
    for token, lines in done:
        for store in _stores():
            try:
                store.remove(token, lines)
            except Exception as error:
                log.warning("fetch witnesses of %s not dropped from %s: %s", token,
                            type(store).__name__, error)


# --- folding everything: periodically, or by manage.py flush_fetches -----------------------


def flush(limit: int | None = None) -> int:
    """Fold every witness into the database, ``BATCH`` items a statement; return how
    many items changed. Witnesses of tokens the database does not know are dropped once
    they are ``STALE_S`` old."""
    changed = 0
    for store in _stores():
        tokens = store.tokens()[:limit]
        for at in range(0, len(tokens), BATCH):
            batch = tokens[at:at + BATCH]
            lines = store.read(batch)  # before the write lock: it is held for the fold only
            if not lines:
                continue
            batch = list(lines)
            with transaction.atomic():
                # Rows an answer holds are left to it (skip_locked: no deadlock with it).
                rows = {token: (pk, fetched, fetched_at) for pk, token, fetched, fetched_at in
                        TrialItem.objects.select_for_update(skip_locked=True)
                        .filter(token__in=batch).order_by("pk")
                        .values_list("pk", "token", "fetched", "fetched_at")}
                dirty, done = [], []
                for token, witnessed in lines.items():
                    if token not in rows:
                        times = [e[4] for e in map(parse_line, witnessed) if e]
                        if not times or time.time() - max(times) > STALE_S:
                            done.append((token, witnessed))
                        continue
                    pk, fetched, fetched_at = rows[token]
                    merged, merged_at, did = fold(fetched, fetched_at, witnessed)
                    if did:
                        dirty.append(TrialItem(pk=pk, token=token, fetched=merged,
                                               fetched_at=merged_at))
                    done.append((token, witnessed))
                if dirty:
                    TrialItem.objects.bulk_update(dirty, ["fetched", "fetched_at"])
                changed += len(dirty)
            for token, witnessed in done:
                store.remove(token, witnessed)
    return changed


_flusher = None
_flusher_pid = None


def flush_every() -> float:
    return float(getattr(settings, "STUDY_FETCH_FLUSH_S", 0) or 0)


def start_flusher() -> None:
    """Start this process's thread that calls :func:`flush` every ``STUDY_FETCH_FLUSH_S``
    seconds (0: none), once (again after a fork)."""
    global _flusher, _flusher_pid
    if flush_every() <= 0 or (_flusher is not None and _flusher_pid == os.getpid()):
        return
    with _lock:
        if _flusher is not None and _flusher_pid == os.getpid():
            return

        def loop():
            while True:
                time.sleep(max(flush_every(), 1.0))
                if flush_every() <= 0:
                    continue
                try:
                    flush()
                except Exception:
                    log.exception("fetch witnesses not flushed")
                finally:
                    close_old_connections()

        _flusher = threading.Thread(target=loop, name="fetch-flush", daemon=True)
        _flusher_pid = os.getpid()
        _flusher.start()
