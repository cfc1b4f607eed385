"""Start and stop a real gunicorn server of the study app, for load and fault tests.

The server runs the production settings (``DJANGO_DEBUG=0``) on 127.0.0.1 over plain
HTTP (``STUDY_SSL_REDIRECT=0``), against the database named by ``database_url``.
"""

import os
import secrets
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GUNICORN = Path(sys.executable).with_name("gunicorn")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def server_env(database_url: str, var_dir: Path, **extra) -> dict:
    """Return the environment of a production-settings server on plain local HTTP."""
    env = dict(os.environ)
    env.update(
        DJANGO_DEBUG="0",
        DJANGO_SECRET_KEY=env.get("DJANGO_SECRET_KEY") or secrets.token_urlsafe(50),
        DJANGO_ALLOWED_HOSTS="127.0.0.1,localhost",
        STUDY_SSL_REDIRECT="0",
        STUDY_HSTS_SECONDS="0",
        DATABASE_URL=database_url,
        STUDY_DATABASE_URL=database_url,
        STUDY_VAR_DIR=str(var_dir),
        PYTHONPATH=str(ROOT),
        **extra,
    )
    return env


class Server:
    """A gunicorn master and its workers in their own process group."""

    def __init__(self, env: dict, workers: int = 3, port: int | None = None,
                 settings: str = "studyapp.settings", log: Path | None = None,
                 root: Path = ROOT):
        self.env = dict(env, DJANGO_SETTINGS_MODULE=settings)
        self.root = Path(root)  # the checkout whose code is served
        self.start_timeout = 30.0
        self.workers = workers
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.log = log
        self.process = None

    def collectstatic(self) -> None:
        subprocess.run(
            [sys.executable, "manage.py", "collectstatic", "--noinput", "--verbosity", "0"],
            cwd=self.root, env=self.env, check=True,
        )

    def start(self, timeout: float = 30) -> "Server":
        out = open(self.log, "ab") if self.log else subprocess.DEVNULL
        self.process = subprocess.Popen(
            [str(GUNICORN), "studyapp.wsgi", "--bind", f"127.0.0.1:{self.port}",
             "--workers", str(self.workers), "--timeout", "30", "--backlog", "2048",
             "--graceful-timeout", "5"],
            cwd=self.root, env=self.env, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True,  # its own process group: kill -9 reaches every worker
        )
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.process.poll() is not None:
                raise RuntimeError(f"gunicorn exited with {self.process.returncode}")
            try:
                urllib.request.urlopen(self.url + "/admin/login/", timeout=2).read()
                return self
            except OSError:
                time.sleep(0.2)
        self.stop()
        raise RuntimeError(f"gunicorn did not answer on {self.url} within {timeout} s")

    def kill(self) -> None:
        """kill -9 the master and every worker at once."""
        if self.process and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait(10)

    def stop(self) -> None:
        """Stop gracefully (SIGTERM), then kill what is left."""
        if self.process and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGTERM)
            try:
                self.process.wait(15)
            except subprocess.TimeoutExpired:
                self.kill()

    def __enter__(self):
        return self.start(self.start_timeout)

    def __exit__(self, *exc):
        self.stop()


def create_database(name: str) -> str:
    """Create a fresh PostgreSQL database on 127.0.0.1 and return its URL."""
    subprocess.run(["createdb", "-h", "127.0.0.1", "-U", "postgres", name], check=True)
    return f"postgres://postgres@127.0.0.1:5432/{name}"


def drop_database(name: str) -> None:
    subprocess.run(["dropdb", "-h", "127.0.0.1", "-U", "postgres", "--if-exists", "--force", name],
                   check=False)
