"""Serve a stimulus file with HTTP Range support and nothing that names it.

Browsers fetch video in byte ranges (to seek and to read the moov atom); Django's
FileResponse answers every request in full and adds a filename header, so clips are
served here instead. No Last-Modified either: render times could differ by source.

Files are read through Django's storage API (``default_storage``: the file system under
``MEDIA_ROOT``, or S3-compatible object storage), never from a public storage URL.

Every delivery has bytes of its own (:mod:`rendering.delivery`): the stored file is
turned into this delivery's bytes by a seed that is an HMAC of the site's secret and the
delivery's token (:func:`delivery_seed`), so the byte ranges of one delivery always agree
and no two deliveries share a hash. A stored file the transformation cannot read (not
laid out as the build writes mp4s) is sent as stored, and the blindness audit says so.
"""

import logging
import os
import re
import struct
import tempfile
from pathlib import Path
from urllib.parse import urlsplit

from django.core.files.storage import default_storage
from django.http import HttpResponse, HttpResponseNotModified, StreamingHttpResponse
from django.utils.crypto import salted_hmac

from rendering.delivery import deliver
from rendering.padding import PaddingError
from rendering.player import PayloadError

logger = logging.getLogger(__name__)

RANGE = re.compile(r"^bytes=(\d*)-(\d*)$")
CHUNK = 64 * 1024
FOLDER = "stimuli"
SEED_SALT = "studyapp.stimuli.media.delivery"


def delivery_seed(token: str) -> bytes:
    """Return the seed of one delivery's bytes: an HMAC-SHA256 of the site's secret and
    the delivery's token (unguessable without the secret, the same for every request)."""
    return salted_hmac(SEED_SALT, token, algorithm="sha256").digest()


# Stored files already reported as sent as stored, with the reason, by this process: one
# warning a file and reason, not one a delivery (unpadded clips would fill the log).
SENT_AS_STORED: set = set()


def delivered_bytes(data: bytes, kind: str, seed: bytes, name: str = "") -> bytes:
    """Return one delivery's bytes of the stored file ``data`` (the stored bytes when the
    file is not one the transformation reads; logged once per file and process)."""
    try:
        out = deliver(data, kind, seed)
        reason = "it has no padding to lay out anew (build it with build_stimuli)"
    except (PaddingError, PayloadError, ValueError, IndexError, struct.error) as error:
        out, reason = data, str(error)
    if out == data and (name or kind, reason) not in SENT_AS_STORED:
        SENT_AS_STORED.add((name or kind, reason))
        logger.warning("%s is sent as stored, the same bytes for every delivery: %s",
                       name or kind, reason)
    return out


def is_stimulus_name(name) -> bool:
    """Whether ``name`` is a plain relative storage name under ``stimuli/``.

    No absolute names, no ``..`` or ``.`` parts, no empty parts, no backslashes.
    """
    if not isinstance(name, str) or "\\" in name or "\x00" in name:
        return False
    parts = name.split("/")
    return (
        len(parts) >= 2
        and parts[0] == FOLDER
        and all(part not in ("", ".", "..") for part in parts)
    )


class _LastChunk:
    """Calls ``on_sent`` of a response body as its last chunk goes to the server.

    ``on_sent()`` runs *before* the last chunk is handed over, so what it records is on
    record before the client can have the last byte, however long this thread then waits
    to run again. It may return an object with ``done()`` (called once the server took
    the chunk and asked for more) and ``undo()`` (called instead when it did not: the
    client went away, and the response was closed at that chunk).
    """

    on_sent = None
    _pending = None

    def _send_last(self, chunk):
        if self.on_sent is None:
            yield chunk
            return
        self._pending = self.on_sent()
        try:
            yield chunk
        except GeneratorExit:
            self._settle(False)
            raise
        self._settle(True)

    def _settle(self, taken: bool) -> None:
        pending, self._pending = self._pending, None
        action = getattr(pending, "done" if taken else "undo", None)
        if action is not None:
            action()


class _Span(_LastChunk):
    """``length`` bytes of an open storage file from ``start``; ``close`` closes the file.

    A file of django-storages' S3 backend (it has the boto3 ``obj``) is read with a
    ranged GET, so a seek in a long clip does not download all of it. ``on_sent`` is
    called as the last byte goes to the server (:class:`_LastChunk`).
    """

    def __init__(self, f, start: int, length: int, on_sent=None):
        self.f, self.start, self.length = f, start, length
        self.body = None
        self.on_sent = on_sent

    def __iter__(self):
        length = self.length
        if length <= 0:
            return
        obj = getattr(self.f, "obj", None)
        if obj is not None and hasattr(obj, "get"):
            self.body = obj.get(Range=f"bytes={self.start}-{self.start + length - 1}")["Body"]
            read = self.body.read
        else:
            self.f.seek(self.start)
            read = self.f.read
        while length > 0:
            chunk = read(min(CHUNK, length))
            if not chunk:
                return
            length -= len(chunk)
            if length > 0:
                yield chunk
            else:
                yield from self._send_last(chunk)

    def close(self):
        self._settle(False)  # closed at the last chunk: the server did not take it
        try:
            if self.body is not None:
                self.body.close()
        finally:
            self.f.close()


class _Bytes(_LastChunk):
    """``length`` bytes of ``data`` from ``start``, in chunks; ``on_sent`` as for _Span."""

    def __init__(self, data: bytes, start: int, length: int, on_sent=None):
        self.data, self.start, self.length = data, start, length
        self.on_sent = on_sent

    def __iter__(self):
        view = memoryview(self.data)[self.start:self.start + self.length]
        for at in range(0, len(view), CHUNK):
            chunk = bytes(view[at:at + CHUNK])
            if at + CHUNK < len(view):
                yield chunk
            else:
                yield from self._send_last(chunk)

    def close(self):
        self._settle(False)


def _read_all(f) -> bytes:
    """Return a storage file's bytes (one GET of an S3 object, not its spooled copy)."""
    obj = getattr(f, "obj", None)
    if obj is not None and hasattr(obj, "get"):
        body = obj.get()["Body"]
        try:
            return body.read()
        finally:
            body.close()
    f.seek(0)
    return f.read()


def parse_range(header: str, size: int):
    """Return ``(start, end)`` inclusive for a single byte range, None to send it all.

    Raise ValueError when the range cannot be satisfied.
    """
    match = RANGE.match(header.strip())
    if not match or match.groups() == ("", ""):
        return None  # several ranges or a malformed header: the whole file is allowed
    first, last = match.groups()
    if first == "":
        start, end = max(0, size - int(last)), size - 1
    else:
        start, end = int(first), min(int(last), size - 1) if last else size - 1
    if start >= size or start > end:
        raise ValueError(header)
    return start, end


def file_response(request, name: str, content_type: str, etag: str, on_sent=None,
                  delivery: tuple[str, bytes] | None = None):
    """Return the stored file ``name`` (or the requested byte range of it) as an
    anonymous response; the response closes the file.

    ``name`` must be a stimulus name under ``stimuli/``, opened through
    ``default_storage``. Raise FileNotFoundError when it is not one, or nothing is
    stored under it. ``on_sent(start, end, size)`` is called as the last of the bytes
    ``start`` to ``end`` (inclusive) of a GET goes to the server (:class:`_LastChunk`: it
    may return what to do once that chunk was taken, or was not). ``delivery`` is ``(kind, seed)``:
    send that delivery's bytes (:func:`delivered_bytes`, the same size) instead of the
    stored ones.
    """
    if not is_stimulus_name(name):
        raise FileNotFoundError(f"not a stimulus name: {name!r}")
    f = default_storage.open(name, "rb")
    try:
        size = f.size
    except BaseException:
        f.close()
        raise
    headers = {
        "Accept-Ranges": "bytes",
        "ETag": etag,
        "Cache-Control": "private, max-age=86400",
    }
    if request.headers.get("If-None-Match") == etag:
        f.close()
        return HttpResponseNotModified(headers=headers)
    span = None
    if_range = request.headers.get("If-Range")
    if "Range" in request.headers and (if_range is None or if_range == etag):
        try:
            span = parse_range(request.headers["Range"], size)
        except ValueError:
            f.close()
            return HttpResponse(status=416, headers={**headers, "Content-Range": f"bytes */{size}"})
    start, end = span or (0, size - 1)
    headers["Content-Length"] = str(end - start + 1)
    if span:
        headers["Content-Range"] = f"bytes {start}-{end}/{size}"
    status = 206 if span else 200
    if request.method == "HEAD":
        f.close()
        return HttpResponse(status=status, content_type=content_type, headers=headers)
    done = (lambda: on_sent(start, end, size)) if on_sent is not None else None
    if delivery is None:
        body = _Span(f, start, end - start + 1, done)
    else:
        try:
            data = _read_all(f)
        finally:
            f.close()
        if len(data) != size:
            raise FileNotFoundError(f"{name} changed while it was read")
        body = _Bytes(delivered_bytes(data, *delivery, name=name), start, end - start + 1, done)
    return StreamingHttpResponse(body, status=status, content_type=content_type, headers=headers)
def merge_ranges(ranges) -> list[list[int]]:
    """Return inclusive byte ranges merged where they touch or overlap, sorted."""
    out: list[list[int]] = []
    for start, end in sorted([int(a), int(b)] for a, b in ranges):
        if out and start <= out[-1][1] + 1:
            out[-1][1] = max(out[-1][1], end)
        else:
            out.append([start, end])
    return out




# --- bytes sent by the proxy (X-Accel-Redirect) -------------------------------------------

DELIVERIES = "deliveries"
# The stimulus field holding each kind of clip file a page names.
STIMULUS_FILES = {"mp4": "video", "png": "poster", "motion": "motion"}


def delivery_name(token: str, ext: str) -> str:
    """Return the storage name of one delivery's file: its opaque token, nothing more."""
    return f"{DELIVERIES}/{token}.{ext}"


def write_delivery(name: str, token: str, ext: str, seed: bytes) -> None:
    """Write the delivery ``token``'s bytes of the stored stimulus file ``name`` into the
    deliveries folder under ``MEDIA_ROOT`` (once; a second call finds it there).

    The file is written to a temporary name and renamed (two workers writing the same
    delivery at once both leave whole, identical files). Its modification time is set to
    the epoch, so the proxy's ``Last-Modified`` tells nothing of when or what was
    rendered. Raise FileNotFoundError as :func:`file_response` does.
    """
    if not is_stimulus_name(name):
        raise FileNotFoundError(f"not a stimulus name: {name!r}")
    target = Path(default_storage.path(delivery_name(token, ext)))
    if target.exists():
        return
    with default_storage.open(name, "rb") as f:
        data = _read_all(f)
    out = delivered_bytes(data, ext, seed, name=name)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, temporary = tempfile.mkstemp(dir=target.parent, prefix=".part-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(out)
        os.chmod(temporary, 0o644)  # the proxy's user reads it
        os.utime(temporary, (0, 0))
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def writes_ahead() -> bool:
    """Whether trial pages write their clips' delivery files ahead: behind nginx
    (``STUDY_ACCEL_REDIRECT``), with the media in this machine's folder, and
    ``STUDY_DELIVER_AHEAD`` on (the default; ``manage.py nginx_config`` reads it too)."""
    from django.conf import settings

    return (proxied(getattr(settings, "STUDY_ACCEL_REDIRECT", ""))
            and getattr(settings, "STUDY_DELIVER_AHEAD", True) and local_media())


def deliver_ahead(stimulus, token: str, ext: str) -> bool:
    """Write the delivery ``token``'s ``ext`` file before the page naming it is sent (when
    :func:`writes_ahead`).

    nginx's clip location (:func:`studyapp.participation.proxy_log.nginx_config`) tries
    that file first, so the participant's fetch never waits for an app worker (no token
    lookup, no Python); only a fetch whose file is missing goes on to the clip view
    (:func:`accel_response`). Return whether the file is there. A failed write is logged
    and leaves the view to try again (the page is not lost for it)."""
    if not writes_ahead():
        return False
    name = getattr(stimulus, STIMULUS_FILES[ext], "")
    if not name:
        return False
    try:
        write_delivery(name, token, ext, delivery_seed(token))
    except (OSError, ValueError, PaddingError, PayloadError) as error:
        logger.warning("could not write delivery %s.%s ahead (%s); its clip view will try again",
                       token, ext, error)
        return False
    return True


def local_media() -> bool:
    """Whether the media live in a folder of this machine (not in a bucket)."""
    try:
        default_storage.path(DELIVERIES)
    except NotImplementedError:
        return False
    return True


def proxied(location: str) -> bool:
    """Whether clips are handed to the proxy under ``location`` (``STUDY_ACCEL_REDIRECT``):
    from the media folder, or from an S3 bucket through a presigned URL of the delivery's
    object (:func:`accel_response`)."""
    return bool(location)


def upload_delivery(name: str, token: str, ext: str, seed: bytes) -> str:
    """Upload the delivery ``token``'s bytes of ``name`` as an object of its own (once;
    remembered in the cache) and return its storage name."""
    from django.core.cache import cache
    from django.core.files.base import ContentFile

    if not is_stimulus_name(name):
        raise FileNotFoundError(f"not a stimulus name: {name!r}")
    target = delivery_name(token, ext)
    key = f"delivery:{target}"
    try:
        known = cache.get(key)
    except Exception:  # the cache is down: ask the bucket
        known = None
    if not known and not default_storage.exists(target):
        with default_storage.open(name, "rb") as f:
            data = _read_all(f)
        default_storage.save(target, ContentFile(delivered_bytes(data, ext, seed, name=name)))
    try:
        cache.set(key, 1, timeout=24 * 3600)
    except Exception:
        pass
    return target


def accel_response(request, name: str, content_type: str, token: str, ext: str, seed: bytes,
                   location: str) -> HttpResponse:
    """Return an empty response that tells nginx to send the delivery's file itself:
    ``X-Accel-Redirect: <location><token>.<ext>``, an internal location (nginx consumes the
    header; the browser sees the opaque clip URL and the file's bytes only). nginx answers
    byte ranges and conditional requests; its access log of that location says which
    bytes went out (:mod:`studyapp.participation.proxy_log`). With the media in an S3
    bucket the delivery is an object of its own (``deliveries/<token>.<ext>``), fetched by
    nginx with a presigned URL from its internal location ``<location>s3/``."""
    response = HttpResponse(content_type=content_type)
    if local_media():
        write_delivery(name, token, ext, seed)
        response["X-Accel-Redirect"] = f"{location}{token}.{ext}"
    else:
        # A bucket: nginx fetches the delivery's object with a presigned URL valid for a
        # minute (in the header, which nginx consumes) from its location <location>s3/.
        url = urlsplit(default_storage.url(upload_delivery(name, token, ext, seed), expire=60))
        response["X-Accel-Redirect"] = f"{location}s3{url.path}?{url.query}"
    response["Cache-Control"] = "private, max-age=86400"
    return response
