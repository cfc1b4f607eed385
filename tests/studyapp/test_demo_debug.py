"""``make demo ADDR=0.0.0.0:PORT`` listens on every interface: it serves with DEBUG off.

Django's debug pages list the URL patterns, settings and paths of the machine to anyone
who asks for a missing page (or breaks one). The demo keeps them on loopback only.
"""

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from studyapp.stimuli.management.commands.demo import is_loopback

ROOT = Path(__file__).resolve().parents[2]
SMALL = ["--only", "ranking", "--size", "64", "--actions", "walk", "--clips-per-source", "1"]
TECHNICAL_404 = "Using the URLconf defined in"


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def fetch(url: str) -> tuple[int, str]:
    try:
        with urllib.request.urlopen(url, timeout=10) as response:
            return response.status, response.read().decode("utf-8", "replace")
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode("utf-8", "replace")


def serve_demo(var: Path, addr: str, port: int, paths: list[str]) -> tuple[dict, str]:
    """Run ``manage.py demo --addr addr`` until it answers on 127.0.0.1:``port``; return the
    status and body of each path, and what the command printed."""
    environ = {k: v for k, v in os.environ.items()
               if not k.startswith(("DJANGO_", "STUDY_")) and k != "DATABASE_URL"}
    environ.update(STUDY_VAR_DIR=str(var), PYOPENGL_PLATFORM="egl")
    log = var.parent / f"demo-{port}.log"
    with open(log, "w") as out:
        demo = subprocess.Popen([sys.executable, "manage.py", "demo", "--addr", addr, *SMALL],
                                cwd=ROOT, env=environ, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)
    try:
        deadline = time.monotonic() + 600
        while True:
            assert demo.poll() is None, f"the demo stopped: {log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, f"the demo never served: {log.read_text()[-3000:]}"
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.5)
        pages = {path: fetch(f"http://127.0.0.1:{port}{path}") for path in paths}
    finally:
        os.killpg(demo.pid, signal.SIGTERM)  # the demo and the server it started
        demo.wait(30)
    return pages, log.read_text()


def test_loopback_is_this_machine_only():
    assert all(map(is_loopback, ["127.0.0.1", "127.0.0.2", "::1", "localhost"]))
    assert not any(map(is_loopback, ["0.0.0.0", "::", "192.168.1.5", "study.example.org"]))


@pytest.mark.slow
def test_the_demo_serves_with_debug_off_unless_on_loopback(tmp_path):
    var = tmp_path / "var"
    paths = ["/no-such-page/", "/static/survey/survey.css", "/s/demo-ranking/"]
    port = free_port()
    public, printed = serve_demo(var, f"0.0.0.0:{port}", port, paths)
    assert "DEBUG is off" in printed
    status, body = public["/no-such-page/"]
    assert status == 404 and TECHNICAL_404 not in body and str(ROOT) not in body
    assert public["/static/survey/survey.css"][0] == 200  # the page still has its styles
    assert public["/s/demo-ranking/"][0] == 200

    port = free_port()
    local, printed = serve_demo(var, f"127.0.0.1:{port}", port, paths[:1])
    assert "DEBUG is off" not in printed
    assert TECHNICAL_404 in local["/no-such-page/"][1]  # the check above is not vacuous
