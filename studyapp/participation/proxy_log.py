"""Clips sent by nginx: its configuration, and its access log read into fetch witnesses.

With ``STUDY_ACCEL_REDIRECT`` set (and the media in a local folder) the request that
sends a trial page writes its clips' delivery files first
(:func:`studyapp.stimuli.media.deliver_ahead`), and nginx's clip location sends each
from there without asking the app: no token lookup, no Python, no gunicorn worker. A clip
URL with no such file (an S3 bucket, a write that failed) goes to the clip view
(``survey.views.clip``), which authorises the opaque token, writes the file once
(:func:`studyapp.stimuli.media.accel_response`) and hands it to nginx's ``internal``
location. The browser sees the clip URL it asked for and the file's bytes: nginx
consumes the ``X-Accel-Redirect`` header, and the internal location cannot be asked for
from outside.

The server still decides who watched. Both locations have an access log of their own
(:data:`LOG_FORMAT`) that nginx writes when a response is over, with the bytes it sent
and whether the response was sent whole (``$request_completion``). :func:`follow`
(``manage.py follow_fetches``, started beside nginx by ``make serve``) reads new lines
as they come and writes each response that nginx sent whole as a witness
(:mod:`~studyapp.participation.fetch_log`: Redis, or this machine's spool), from where
the answer's check and the flushing fold them into the database as before. A response
cut off (a bot that reads half a clip and hangs up) is written as not whole and counts
for nothing; a byte range sent whole counts for its range, as with the view: the file
counts as fetched when the ranges cover it. The log's offset is kept beside it, so a
restarted follower goes on where it stopped (reading a line twice does no harm:
witnesses fold idempotently).
"""

from __future__ import annotations

import logging
import os
import re
import time
from pathlib import Path

from studyapp.participation import fetch_log

log = logging.getLogger(__name__)

# One line per response of a clip location: when it ended, what was sent.
LOG_FORMAT = "$msec $status $body_bytes_sent $request_completion $uri $sent_http_content_range"
CONTENT_RANGE = re.compile(r"^bytes (\d+)-(\d+)/(\d+)$")


def witness_of(line: str):
    """Return ``(token, witness line)`` of a whole response in the access log, or None
    (a response cut off, not a clip's bytes, a malformed line)."""
    parts = line.strip().split(None, 5)
    if len(parts) < 5:
        return None
    at, status, sent, complete, uri = parts[:5]
    crange = parts[5] if len(parts) > 5 else "-"
    if complete != "OK" or not sent.isdigit():
        return None
    token, _, ext = uri.rsplit("/", 1)[-1].rpartition(".")
    if ext not in fetch_log.EXTS or not fetch_log.TOKEN.match(token):
        return None
    sent = int(sent)
    if status == "200":
        if sent <= 0:
            return None
        start, end, size = 0, sent - 1, sent
    elif status == "206":
        match = CONTENT_RANGE.match(crange)
        if not match:
            return None  # several ranges in one response: not counted, as by the view
        start, end, size = map(int, match.groups())
        if sent != end - start + 1:
            return None
    else:
        return None
    try:
        when = float(at)
    except ValueError:
        return None
    return token, fetch_log.make_line(ext, start, end, size, when)


def record(lines) -> int:
    """Write the witnesses of ``lines`` (access-log lines); return how many."""
    found = [w for w in map(witness_of, lines) if w]
    store = fetch_log.backend()
    for token, line in found:
        try:
            store.append(token, line)
        except Exception as error:  # Redis down: this machine's spool, as the view does
            log.warning("fetch witness of %s not in %s (%s): the spool instead",
                        token, type(store).__name__, error)
            fetch_log.spool().append(token, line)
    return len(found)


def _load_offset(place: Path) -> tuple[int, int]:
    try:
        inode, offset = place.read_text().split()
        return int(inode), int(offset)
    except (OSError, ValueError):
        return -1, 0


def _save_offset(place: Path, inode: int, offset: int) -> None:
    partial = place.with_name(place.name + ".part")
    partial.write_text(f"{inode} {offset}\n")
    os.replace(partial, place)


def read_new(path, offset_file=None) -> int:
    """Record the witnesses of the lines written to the access log ``path`` since the
    last call (the offset is kept in ``<path>.offset``); return how many. A log that was
    rotated (another file) or truncated is read from its start."""
    path = Path(path)
    place = Path(offset_file) if offset_file else path.with_name(path.name + ".offset")
    inode, offset = _load_offset(place)
    try:
        f = open(path, "rb")
    except FileNotFoundError:
        return 0
    with f:
        stat = os.fstat(f.fileno())
        if stat.st_ino != inode or stat.st_size < offset:
            inode, offset = stat.st_ino, 0
        if stat.st_size == offset:
            return 0
        f.seek(offset)
        data = f.read(stat.st_size - offset)
    end = data.rfind(b"\n") + 1  # a line being written is read next time
    if end == 0:
        return 0
    count = record(data[:end].decode(errors="replace").splitlines())
    _save_offset(place, inode, offset + end)
    return count


def follow(path, poll: float = 0.05, flush_every: float | None = None, stop=None) -> None:
    """Read the access log ``path`` as nginx writes it (every ``poll`` seconds) until
    ``stop()`` is true; fold the witnesses into the database every ``flush_every``
    seconds (default ``STUDY_FETCH_FLUSH_S``; the answers fold their own in any case)."""
    from django.db import close_old_connections

    flush_every = fetch_log.flush_every() if flush_every is None else flush_every
    flushed = time.monotonic()
    while stop is None or not stop():
        try:
            read_new(path)
        except Exception:
            log.exception("access log %s not read", path)
        if flush_every > 0 and time.monotonic() - flushed > flush_every:
            flushed = time.monotonic()
            try:
                fetch_log.flush()
            except Exception:
                log.exception("fetch witnesses not flushed")
            finally:
                close_old_connections()
        time.sleep(poll)


# --- nginx's configuration ------------------------------------------------------------------

NGINX = """\
# Written by `manage.py nginx_config` (make serve): nginx in front of gunicorn; clips'
# bytes from the files their pages wrote ahead, else from the internal location
# {location} (X-Accel-Redirect), logged for `manage.py follow_fetches`.
{user}worker_processes {workers};
pid {run}/nginx.pid;
error_log {run}/error.log warn;
events {{ worker_connections 4096; }}
http {{
    client_body_temp_path {run}/client_body;
    proxy_temp_path {run}/proxy;
    fastcgi_temp_path {run}/fastcgi;
    uwsgi_temp_path {run}/uwsgi;
    scgi_temp_path {run}/scgi;
    server_tokens off;
    sendfile on;
    tcp_nopush on;
    keepalive_timeout 65;
    access_log {access};
    log_format study_fetch '{log_format}';
    upstream study_app {{
        server {upstream};
        keepalive 32;
    }}
    server {{
        listen {listen}{ssl};
        client_max_body_size 1m;
{tls}{real_ip}        location / {{
{app}        }}
        location @app {{
{app}        }}
{ahead}        # Reached only through the clip view's X-Accel-Redirect: a request from
        # outside gets 404. Files named by the delivery's opaque token only.
        location {location} {{
            internal;
            alias {deliveries}/;
            etag off;
            types {{ video/mp4 mp4; image/png png; application/octet-stream motion; }}
            default_type application/octet-stream;
            access_log {fetch_log} study_fetch;
        }}
{s3}    }}
}}
"""

# A clip whose delivery file the page's request wrote ahead (media.deliver_ahead) is sent
# from it without asking the app; any other clip URL goes to the clip view.
AHEAD_LOCATION = """\
        # Clips written ahead by their page: sent without asking the app.
        location ~ "^/c/(?<delivery>[A-Za-z0-9_-]{{8,64}}\\.(?:mp4|png|motion))$" {{
            root {media_root};
            try_files /deliveries/$delivery @app;
            limit_except GET {{ deny all; }}
            etag off;
            add_header Cache-Control "private, max-age=86400";
            types {{ video/mp4 mp4; image/png png; application/octet-stream motion; }}
            default_type application/octet-stream;
            access_log {fetch_log} study_fetch;
        }}
"""

# With the media in an S3 bucket: the clip view's X-Accel-Redirect carries the path and
# presigned query of the delivery's own object; nginx fetches it from the bucket's host
# (the one the storage presigns for) and sends it on, logged as above.
S3_LOCATION = """        location {location}s3/ {{
            internal;
            proxy_pass {endpoint}/;
            proxy_set_header Host {host};
            proxy_set_header Cookie "";
            proxy_set_header Authorization "";
            proxy_set_header X-Forwarded-For "";
            proxy_ssl_server_name on;
            proxy_buffering off;
{hide}            access_log {fetch_log} study_fetch;
        }}
"""
# What S3 (and S3-compatible stores) add that a participant has no use for.
S3_HIDDEN = ["ETag", "Last-Modified", "Set-Cookie", "x-amz-request-id", "x-amz-id-2",
             "x-amzn-requestid", "x-amz-version-id", "x-amz-server-side-encryption",
             "x-amz-storage-class", "x-amz-expiration", "x-amz-checksum-crc32",
             "x-amz-checksum-crc32c", "x-amz-checksum-sha256", "x-amz-meta-mtime",
             "x-amz-mp-parts-count", "x-amz-tagging-count", "x-amz-replication-status",
             "x-amz-restore", "x-amz-object-lock-mode", "x-amz-website-redirect-location"]


def nginx_config(*, listen: str, upstream: str, media_root, fetch_log_path, run_dir,
                 location: str = "/protected-media/", workers: str = "auto",
                 access_log: str = "off", proto: str = "$scheme", user: str = "",
                 real_ip_from=(), tls_cert: str = "", tls_key: str = "",
                 s3_endpoint: str = "", ahead: bool | None = None) -> str:
    """Return an nginx.conf that serves the app from ``upstream`` (gunicorn's
    ``host:port``) on ``listen`` and the deliveries' files under ``location``; ``user``:
    the user of nginx's workers when it is started as root (they read the deliveries);
    ``real_ip_from``: addresses of a balancer in front (HAProxy) whose
    ``X-Forwarded-For`` names the participant (the app's rate limits count that address);
    ``tls_cert`` and ``tls_key``: nginx ends TLS itself on ``listen``; ``s3_endpoint``
    (``scheme://host[:port]``): the bucket's host, when the media are in S3; ``ahead``
    (default: with the media in a local folder): clips the pages wrote ahead
    (:func:`studyapp.stimuli.media.deliver_ahead`) are sent straight from the deliveries
    folder, the clip view asked only for the others."""
    if bool(tls_cert) != bool(tls_key):
        raise ValueError("TLS needs both a certificate and its key")
    tls = (f"        ssl_certificate {tls_cert};\n        ssl_certificate_key {tls_key};\n"
           if tls_cert else "")
    real_ip = "".join(f"        set_real_ip_from {a};\n" for a in real_ip_from)
    if real_ip:
        real_ip += "        real_ip_header X-Forwarded-For;\n"
    location = "/" + location.strip("/") + "/"
    s3 = ""
    if s3_endpoint:
        s3 = S3_LOCATION.format(
            location=location, endpoint=s3_endpoint.rstrip("/"),
            host=s3_endpoint.split("://", 1)[-1].rstrip("/"), fetch_log=Path(fetch_log_path),
            hide="".join(f"            proxy_hide_header {h};\n" for h in S3_HIDDEN))
    app = (f"            proxy_pass http://study_app;\n"
           f"            proxy_http_version 1.1;\n"
           f"            proxy_set_header Connection \"\";\n"
           f"            proxy_set_header Host $http_host;\n"
           f"            proxy_set_header X-Forwarded-For $proxy_add_x_forwarded_for;\n"
           f"            proxy_set_header X-Forwarded-Proto {proto};\n")
    if ahead is None:
        ahead = not s3_endpoint
    ahead_location = (AHEAD_LOCATION.format(media_root=Path(media_root),
                                            fetch_log=Path(fetch_log_path)) if ahead else "")
    return NGINX.format(s3=s3, app=app, ahead=ahead_location, 
        user=f"user {user};\n" if user else "", real_ip=real_ip, tls=tls, ssl=" ssl" if tls_cert else "", workers=workers, run=Path(run_dir), access=access_log, log_format=LOG_FORMAT,
        upstream=upstream, listen=listen, location=location, proto=proto,
        deliveries=Path(media_root) / "deliveries", fetch_log=Path(fetch_log_path))
