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


def setup_django(code: Path) -> None:
    """Set Django up in this process on the app code of checkout ``code`` (its settings
    from the environment) and migrate its database: a benchmark's inner process."""
    sys.path.insert(0, str(code))
    import django
    from django.core.management import call_command

    django.setup()
    call_command("migrate", verbosity=0)


def create_database(name: str) -> str:
    """Create a fresh PostgreSQL database on 127.0.0.1 and return its URL."""
    subprocess.run(["createdb", "-h", "127.0.0.1", "-U", "postgres", name], check=True)
    return f"postgres://postgres@127.0.0.1:5432/{name}"


def drop_database(name: str) -> None:
    subprocess.run(["dropdb", "-h", "127.0.0.1", "-U", "postgres", "--if-exists", "--force", name],
                   check=False)


NGINX = "/usr/sbin/nginx"
HAPROXY = "/usr/sbin/haproxy"


def wait_port(port: int, timeout: float = 15, process=None) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if process is not None and process.poll() is not None:
            raise RuntimeError(f"{process.args[0]} exited with {process.returncode}")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError(f"nothing listens on 127.0.0.1:{port} after {timeout} s")


class Proxy:
    """A proxy (nginx or HAProxy) in the foreground, from a configuration file."""

    def __init__(self, command: list[str], port: int, log: Path | None = None):
        self.command, self.port = command, port
        self.url = f"http://127.0.0.1:{port}"
        self.log = log
        self.process = None

    def start(self) -> "Proxy":
        out = open(self.log, "ab") if self.log else subprocess.DEVNULL
        self.process = subprocess.Popen(self.command, stdout=out, stderr=subprocess.STDOUT,
                                        start_new_session=True)
        wait_port(self.port, process=self.process)
        return self

    def stop(self) -> None:
        if self.process and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGTERM)
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait(10)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


def nginx(env: dict, folder: Path, upstream: str, port: int | None = None,
          ahead: bool = True) -> Proxy:
    """Return nginx (not started) in front of gunicorn at ``upstream``, configured by
    ``manage.py nginx_config`` with the settings of ``env`` (``ahead`` False: the clip
    view is asked for every clip); its clip log is ``folder/fetches.log``."""
    port = port or free_port()
    folder.mkdir(parents=True, exist_ok=True)
    user = ["--user", "root"] if os.geteuid() == 0 else []
    config = subprocess.run(
        [sys.executable, "manage.py", "nginx_config", "--listen", f"127.0.0.1:{port}",
         "--upstream", upstream, "--run-dir", str(folder), "--fetch-log",
         str(folder / "fetches.log"), "--workers", "1", *user,
         *([] if ahead else ["--no-ahead"])],
        cwd=ROOT, env=env, check=True, capture_output=True, text=True).stdout
    (folder / "nginx.conf").write_text(config)
    return Proxy([NGINX, "-p", str(folder), "-c", str(folder / "nginx.conf"),
                  "-e", str(folder / "error.log"), "-g", "daemon off;"], port,
                 log=folder / "nginx.out")


HAPROXY_CONFIG = """\
global
    maxconn 4096
defaults
    mode http
    timeout connect 2s
    timeout client 60s
    timeout server 60s
    retries 3
    option redispatch
    option forwardfor
frontend study
    bind 127.0.0.1:{port}
    default_backend nodes
backend nodes
    balance roundrobin
    timeout check 1s
    default-server inter 500ms fall 2 rise 2
{servers}
"""


def haproxy(folder: Path, upstreams: list[str], port: int | None = None) -> Proxy:
    """Return HAProxy (not started) balancing over ``upstreams`` (``host:port``) round
    robin. Nodes are checked by connecting every 0.5 s (a dead node is out after two
    refused connections; requests it refuses meanwhile are sent to another node). Not by
    an HTTP check: a node whose sync workers are all busy answers it late, and would be
    taken out under exactly the load it is there for."""
    port = port or free_port()
    folder.mkdir(parents=True, exist_ok=True)
    servers = "\n".join(f"    server node{i} {address} check" for i, address in enumerate(upstreams))
    (folder / "haproxy.cfg").write_text(HAPROXY_CONFIG.format(port=port, servers=servers))
    return Proxy([HAPROXY, "-db", "-f", str(folder / "haproxy.cfg")], port,
                 log=folder / "haproxy.out")
