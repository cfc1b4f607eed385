"""Where the study site is served: the address to bind, and the base URL of its links.

Links printed by ``demo`` and ``studies`` start with the address actually served:
``STUDY_BASE_URL`` when set (a public site behind a proxy), else the address the last
``demo`` served on (kept in ``<var>/served.json``), else ``http://127.0.0.1:8000``.
"""

from __future__ import annotations

import errno
import json
import os
import socket
from pathlib import Path

from django.conf import settings

DEFAULT_ADDR = "127.0.0.1:8000"


class AddressError(ValueError):
    """An address to serve on is malformed or already taken; the message says what to do."""


def split_addr(addr: str) -> tuple[str, int]:
    """Return ``(host, port)`` of ``"host:port"`` or ``"port"``."""
    host, sep, port = str(addr).rpartition(":")
    if not sep:
        host, port = "127.0.0.1", addr
    host = host.strip("[]") or "127.0.0.1"
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise AddressError(f"address {addr!r}: write HOST:PORT, e.g. 127.0.0.1:8010 "
                           f"(make demo PORT=8010, or ADDR=0.0.0.0:8010)")
    return host, int(port)


def check_free(addr: str) -> None:
    """Raise :class:`AddressError` when nothing could listen on ``addr`` now."""
    host, port = split_addr(addr)
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        # As the server will: a port left in TIME_WAIT by an earlier run is free.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise AddressError(
                    f"port {port} on {host} is in use (another server, or an earlier "
                    f"`make demo` still running); stop it, or serve elsewhere: "
                    f"make demo PORT={port + 10}"
                ) from None
            raise AddressError(f"cannot serve on {addr}: {exc.strerror}; "
                               f"pick another address with make demo ADDR=HOST:PORT") from None


def url_of(addr: str) -> str:
    host, port = split_addr(addr)
    shown = "127.0.0.1" if host in ("0.0.0.0", "") else host
    shown = f"[{shown}]" if ":" in shown else shown
    return f"http://{shown}:{port}"


def _served_file() -> Path:
    return Path(settings.VAR_DIR) / "served.json"


def record_served(addr: str) -> None:
    """Remember that the site is served on ``addr`` (for ``studies``' links)."""
    path = _served_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"base_url": url_of(addr)}) + "\n")


def base_url() -> str:
    """Return the base URL links start with (see the module docstring)."""
    configured = os.environ.get("STUDY_BASE_URL", "").strip()
    if configured:
        return configured.rstrip("/")
    try:
        return json.loads(_served_file().read_text())["base_url"]
    except (OSError, ValueError, KeyError, TypeError):
        return url_of(DEFAULT_ADDR)
