"""Where an answer request's time goes: py-spy samples of answers through the real pages.

``.venv/bin/python benchmarks/profile_answer.py`` (needs ``pip install py-spy``) creates a
fresh PostgreSQL database and the load test's ranking study, then runs itself under
``py-spy record`` (samples of the process on the CPU): one process
plays ``--participants`` participants through Django's request handling (the test
client, with CSRF checked, production settings), fetching every clip whole (the clip
view) and answering every trial as the trial form posts it (its ``next`` field: a server
that redirects instead is followed, and the redirect's page is part of the answer). Each
sample inside an answer is put in one part, by the innermost frame that names one
(:data:`PARTS`); the split is printed in per cent of the samples and as ms of the
process's CPU time per answer (``time.process_time`` around each answer: a busy machine
stretches the wall clock, not this). The wall-clock time per answer is printed too, and
the PostgreSQL backend's CPU per answer (its /proc entry read around each answer) and this
process's CPU per participant's entry (the link to the first trial page: consent, the
session planned).
``--code DIR`` profiles the app code of another checkout under the same driver.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.server import (  # noqa: E402
    create_database, drop_database, server_env, setup_django)

PY_SPY = Path(sys.executable).with_name("py-spy")
# A stack's part: the innermost frame (``name (file:line)``) matching one of these; the
# last three only count where none of the others matches.
PARTS = [
    ("database (driver, round trips)", r"[(/](psycopg|psycopg2|sqlite3)/"),
    ("ORM (queries built, rows to objects)", r"[(/]django/db/"),
    ("templates", r"[(/]django/(template|templatetags)/"),
    ("fetch check (fetch_log)", r"[(/]studyapp/participation/fetch_log\.py"),
    ("answer form (checks)", r"[(/]django/forms/|[(/]studyapp/participation/answers\.py"),
    ("cookies and CSRF (signing)", r"[(/]django/core/signing|[(/]django/middleware/csrf"),
    ("test client (not in a server)", r"[(/]django/test/"),
    ("request handling (Django)", r"[(/]django/|[(/]whitenoise/"),
    ("views, flow, study types", r"[(/]studyapp/"),
]
TRIAL = re.compile(r'name="trial" value="(\d+)"')
RANK = re.compile(r'name="rank_([A-Za-z0-9_-]+)"')
CSRF = re.compile(r'name="csrfmiddlewaretoken" value="([^"]+)"')
CLIP = re.compile(r'<video src="(/c/[A-Za-z0-9_-]+\.mp4)"')


def part_of(frames: list[str]) -> str:
    """Return the part of a stack: the innermost frame of one of the named libraries
    decides; only a stack with none is the test client's, Django's request handling or
    the app's code (again the innermost frame decides)."""
    for parts in (PARTS[:-3], PARTS[-3:]):
        for frame in reversed(frames):
            for name, pattern in parts:
                if re.search(pattern, frame):
                    return name
    return "other"


def split(raw: Path, marker: str = "answer_request") -> tuple[Counter, int]:
    """Return the samples inside ``marker`` by part, and their total, from py-spy's raw
    (collapsed) output."""
    parts = Counter()
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        frames = stack.split(";")
        at = next((i for i, f in enumerate(frames) if f.startswith(marker + " ")), None)
        if at is not None:
            parts[part_of(frames[at + 1:])] += int(count)
    return parts, sum(parts.values())


SPENT = {"cpu": 0.0, "wall": 0.0, "requests": 0, "db": 0.0, "entry": 0.0}
TICK_S = 1 / os.sysconf("SC_CLK_TCK")


def database_cpu() -> float:
    """Return the CPU seconds this process's PostgreSQL backend has used so far (NaN where
    its /proc entry cannot be read: a server on another machine). The backend's id is
    asked each time, after the reading before an answer and before the one after it: that
    statement's own CPU (a few µs) counts in the answer's."""
    from django.db import connection

    with connection.cursor() as cursor:
        cursor.execute("SELECT pg_backend_pid()")
        pid = cursor.fetchone()[0]
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) * TICK_S  # utime, stime


def answer_request(client, url: str, data: dict) -> str:
    """Post an answer as the trial form does; return the page that follows it."""
    db = database_cpu()  # in clock ticks: summed over every answer, the rounding averages out
    cpu, wall = time.process_time(), time.perf_counter()
    response = client.post(url, data)
    SPENT["requests"] += 1
    if response.status_code in (301, 302):
        response = client.get(response["Location"])
        SPENT["requests"] += 1
    assert response.status_code == 200, response.status_code
    SPENT["cpu"] += time.process_time() - cpu
    SPENT["wall"] += time.perf_counter() - wall
    SPENT["db"] += database_cpu() - db
    return response.content.decode()


def fetch_clips(client, page: str) -> None:
    for url in CLIP.findall(page):
        response = client.get(url)
        assert response.status_code == 200, (url, response.status_code)
        b"".join(response.streaming_content)


def drive(participants: int, trials: int) -> int:
    """Play the participants through the pages; return the answers given."""
    from http.cookies import SimpleCookie

    from django.test import Client

    from benchmarks.loadtest import make_study

    study = make_study("profile", Path(os.environ["STUDY_VAR_DIR"]) / "media", trials=trials)
    answers = 0
    # One client (its handler loads the middleware once, as a server's worker does), each
    # participant in a fresh browser: no cookies.
    client = Client(enforce_csrf_checks=True)
    for i in range(participants):
        client.cookies = SimpleCookie()
        base = f"/s/{study.slug}/"
        cpu = time.process_time()  # the entry: the link to the first trial page
        page = client.get(base, {"PROLIFIC_PID": f"profile-{i}"}, follow=True).content.decode()
        for name, data in (("consent", {"agree": "1"}), ("instructions", {})):
            data["csrfmiddlewaretoken"] = CSRF.search(page).group(1)
            page = client.post(f"{base}{name}/", data, follow=True).content.decode()
        SPENT["entry"] += time.process_time() - cpu
        while (trial := TRIAL.search(page)) is not None:
            fetch_clips(client, page)
            data = {"trial": trial.group(1), "next": "trial",
                    "csrfmiddlewaretoken": CSRF.search(page).group(1)}
            for rank, token in enumerate(RANK.findall(page), 1):
                data[f"plays_{token}"] = "1"
                data[f"rank_{token}"] = str(rank)
            page = answer_request(client, f"{base}trial/", data)
            answers += 1
    return answers


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--participants", type=int, default=40)
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--rate", type=int, default=500, help="py-spy samples a second.")
    parser.add_argument("--code", type=Path, default=None,
                        help="Profile the app code of this checkout.")
    parser.add_argument("--out", type=Path, default=None, help="Keep py-spy's raw output here.")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    code = (args.code or ROOT).resolve()
    if args.inner:
        setup_django(code)
        from django.conf import settings
        from django.core.management import call_command

        call_command("collectstatic", interactive=False, verbosity=0)
        settings.STUDY_WATCH_TIME_FACTOR = 0  # no waiting: the check itself still runs
        answers = drive(args.participants, args.trials)
        print(f"answers={answers} requests={SPENT['requests']} "
              f"cpu_ms={1000 * SPENT['cpu'] / answers:.2f} wall_ms={1000 * SPENT['wall'] / answers:.2f} "
              f"db_ms={1000 * SPENT['db'] / answers:.2f} "
              f"entry_ms={1000 * SPENT['entry'] / args.participants:.1f}")
        return 0
    if not PY_SPY.exists():
        sys.exit(f"{PY_SPY} is missing: install it with `{sys.executable} -m pip install py-spy`")
    name = f"profile_{os.getpid()}"
    var = Path(tempfile.mkdtemp(prefix="profile-var-"))
    url = create_database(name)
    env = server_env(url, var)
    env.update(PYTHONPATH=str(code), DJANGO_ALLOWED_HOSTS="testserver",
               DJANGO_SETTINGS_MODULE="studyapp.settings")
    raw = args.out or var / "answer.raw"
    try:
        run = subprocess.run(
            [str(PY_SPY), "record", "--rate", str(args.rate), "--format", "raw",
             "--output", str(raw), "--", sys.executable, __file__, "--inner",
             "--participants", str(args.participants), "--trials", str(args.trials),
             "--code", str(code)],
            env=env, cwd=code, capture_output=True, text=True, check=False,
        )
        found = re.search(r"answers=(\d+)", run.stdout)
        if run.returncode or not found:
            sys.exit(f"the profiled run failed:\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}")
    finally:
        drop_database(name)
    figures = dict(re.findall(r"(\w+)=(\S+)", run.stdout))
    cpu_ms = float(figures["cpu_ms"])
    parts, total = split(raw)
    print(f"code={'this checkout' if code == ROOT else code} answers={figures['answers']} "
          f"requests={figures['requests']} cpu_ms_per_answer={cpu_ms:.2f} "
          f"wall_ms_per_answer={figures['wall_ms']} (this process's CPU; the database's below)")
    if "db_ms" in figures:  # an older driver's code may not print them
        db = "not measured (no /proc entry of its process here)" if figures["db_ms"] == "nan" \
            else f"{figures['db_ms']} ms"
        print(f"the database server's CPU per answer: {db}; the entry (link "
              f"to the first trial page, the session planned) per participant: "
              f"{figures['entry_ms']} ms of this process's CPU")
    for part, samples in parts.most_common():
        print(f"  {part:40s} {100 * samples / total:5.1f} %  {cpu_ms * samples / total:6.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
