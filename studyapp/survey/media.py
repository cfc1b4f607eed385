"""Serve a stimulus file with HTTP Range support and nothing that names it.

Browsers fetch video in byte ranges (to seek and to read the moov atom); Django's
FileResponse answers every request in full and adds a filename header, so clips are
served here instead. No Last-Modified either: render times could differ by source.
"""

import re
from pathlib import Path

from django.http import HttpResponse, HttpResponseNotModified, StreamingHttpResponse

RANGE = re.compile(r"^bytes=(\d*)-(\d*)$")
CHUNK = 64 * 1024


def _read(path: Path, start: int, length: int):
    with open(path, "rb") as f:
        f.seek(start)
        while length > 0:
            chunk = f.read(min(CHUNK, length))
            if not chunk:
                return
            length -= len(chunk)
            yield chunk


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


def file_response(request, path: Path, content_type: str, etag: str):
    """Return the file (or the requested byte range of it) as an anonymous response."""
    size = path.stat().st_size
    headers = {
        "Accept-Ranges": "bytes",
        "ETag": etag,
        "Cache-Control": "private, max-age=86400",
    }
    if request.headers.get("If-None-Match") == etag:
        return HttpResponseNotModified(headers=headers)
    span = None
    if_range = request.headers.get("If-Range")
    if "Range" in request.headers and (if_range is None or if_range == etag):
        try:
            span = parse_range(request.headers["Range"], size)
        except ValueError:
            return HttpResponse(status=416, headers={**headers, "Content-Range": f"bytes */{size}"})
    start, end = span or (0, size - 1)
    headers["Content-Length"] = str(end - start + 1)
    if span:
        headers["Content-Range"] = f"bytes {start}-{end}/{size}"
    status = 206 if span else 200
    if request.method == "HEAD":
        return HttpResponse(status=status, content_type=content_type, headers=headers)
    body = _read(path, start, end - start + 1)
    return StreamingHttpResponse(body, status=status, content_type=content_type, headers=headers)
