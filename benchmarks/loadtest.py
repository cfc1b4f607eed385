"""Load test: N bot participants against a real gunicorn + PostgreSQL server.

``make loadtest`` (or ``.venv/bin/python benchmarks/loadtest.py --participants 500``):
creates a fresh PostgreSQL database, a ranking study of tiny generated clips (``--study
mp4``: videos; ``--study webgl``: the in-page player's motion payloads, the mp4 as
fallback), starts gunicorn (production settings, several workers) on 127.0.0.1, and runs
every participant as a coroutine of one light asyncio client process (enter, consent,
start, answer every trial through the real pages, fetching each clip whole as a browser
does and reporting it played once, optionally "watching" each trial for ``--think``
seconds first). Participants run ``--concurrency`` at a time (a closed loop), or arrive
over time as a crowd platform sends them (``--arrivals 2000 --over 300``: an open loop,
see :func:`arrival_times`). The answer form's ``next`` field is posted as a browser posts
it: a server that answers with the next trial saves the second request, one that
redirects is followed. ``--code DIR`` serves the app code of another checkout (the same
client and settings against, e.g., the previous release). ``--crowd prolific`` makes the
study a Prolific one entered from its link (its three ids; no time limit of its own, so
Prolific's default from the study's minutes applies), as a launch on Prolific is.

It then stops the server and checks the database: stored answers == acknowledged
answers, no duplicates, every stored ranking a permutation, judgements per stimulus
balanced. It reports the answer's latency (the submit until the next page is in hand)
apart from the clips' time to first byte, p50 and p99, on the line
``acknowledged=N stored=N duplicates=0 answer_p50_ms=... answer_p99_ms=...
clip_ttfb_p50_ms=... clip_ttfb_p99_ms=... answers_per_s=...``, followed by the answers'
p50/p99 per ``--window`` seconds of the run, by when they were sent.
"""

import argparse
import asyncio
import hashlib
import http.client
import os
import random
import re
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from urllib.parse import urlencode, urlsplit

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.server import Server, create_database, drop_database, nginx, server_env  # noqa: E402

CSRF = re.compile(r'name="csrfmiddlewaretoken" value="([^"]+)"')
TRIAL = re.compile(r'name="trial" value="(\d+)"')
RANK = re.compile(r'name="rank_([A-Za-z0-9_-]+)"')
CLIP = re.compile(r'<video src="(/c/[A-Za-z0-9_-]+\.mp4)"')
MOTION = re.compile(r'<motion-player data-src="(/c/[A-Za-z0-9_-]+\.motion)"')
TIMEOUT = 60
# The server takes an answer only once the clips were fetched whole and have had time to
# play (their length: the tiny load-test clips last 0.4 s) since the page was served.
CLIP_SECONDS = 0.4
# ``--crowd prolific``: a study on Prolific with its codes and no time limit of its own
# (Prolific's default, three times the study's minutes, applies), entered as from its link.
PROLIFIC_STUDY = "60aaca280709ee40ec37d488"
PROLIFIC_CROWD = {"platform": "prolific",
                  "codes": {"completed": "LOADDONE", "failed_attention": "LOADFAIL",
                            "no_consent": "LOADNO"}}


class HttpError(RuntimeError):
    pass


class Bot:
    """What a bot participant knows: its cookies, the page it is on, its answers.

    Cookies are kept by hand (name=value, sent back always): the production settings
    mark them Secure, and this client talks plain HTTP to 127.0.0.1. Subclasses move
    the bytes (blocking ``http.client`` or asyncio streams).
    """

    def __init__(self, url: str, slug: str, person: str, rng: random.Random | None = None):
        parts = urlsplit(url)
        self.host, self.port = parts.hostname, parts.port
        self.slug = slug
        self.person = person
        self.rng = rng or random.Random(person)
        self.cookies: dict[str, str] = {}
        self.page = ""
        self.at = ""
        self.submits: list[tuple[int, int, float]] = []  # (trial id, status, seconds)
        # Post the trial form's ``next`` field as a browser does: the next trial comes
        # in the answer's response where the server supports it.
        self.one_request = False
        self.press = 0.0  # seconds after the clips' time before the answer goes
        self.answer_seconds: list[float] = []  # submit until the next page is in hand
        self.answer_at: list[float] = []  # when each answer went (time.monotonic)
        self.prolific = False  # enter with Prolific's ids (``--crowd prolific``)
        self.clip_ttfb: list[float] = []  # each clip: request until its first byte

    def entry_query(self) -> str:
        """Return the entry link's query: the ids a crowd platform adds to it (Prolific's
        three, of 24 hex digits, for a study on Prolific)."""
        if not self.prolific:
            return urlencode({"PROLIFIC_PID": self.person})
        pid = hashlib.sha256(self.person.encode()).hexdigest()[:24]
        return urlencode({"PROLIFIC_PID": pid, "STUDY_ID": PROLIFIC_STUDY,
                          "SESSION_ID": hashlib.sha256(pid.encode()).hexdigest()[:24]})

    def path(self, name: str = "") -> str:
        return f"/s/{self.slug}/{name + '/' if name else ''}"

    def headers(self, data: dict | None, headers=None) -> tuple[dict, str | None]:
        """Return the request headers and the urlencoded body of a request."""
        body = urlencode(data) if data is not None else None
        sent = {"Host": f"{self.host}:{self.port}"}
        if self.cookies:
            sent["Cookie"] = "; ".join(f"{k}={v}" for k, v in self.cookies.items())
        if body is not None:
            sent["Content-Type"] = "application/x-www-form-urlencoded"
        sent.update(headers or {})
        return sent, body

    def keep_cookies(self, headers) -> None:
        for header, value in headers:
            if header.lower() == "set-cookie":
                name, _, rest = value.partition("=")
                self.cookies[name.strip()] = rest.split(";", 1)[0]

    def form(self, data: dict) -> dict:
        """Return ``data`` with the CSRF token of the page the bot is on."""
        token = CSRF.search(self.page)
        return {"csrfmiddlewaretoken": token.group(1) if token else "", **data}

    def answer_data(self) -> dict:
        """Return a valid answer to the trial on the page: a random ranking, one play each."""
        trial = TRIAL.search(self.page).group(1)
        tokens = RANK.findall(self.page)
        ranks = self.rng.sample(range(1, len(tokens) + 1), len(tokens))
        data = {"trial": trial, **({"next": "trial"} if self.one_request else {})}
        for token, rank in zip(tokens, ranks):
            data[f"plays_{token}"] = "1"
            data[f"rank_{token}"] = str(rank)
        return data

    def on_trial(self) -> bool:
        return self.at.endswith("/trial/")

    def clips(self) -> list[str]:
        """Return the clip URLs of the trial on the page as a browser fetches them: the
        in-page player's payloads where the page has them (the videos are then not
        preloaded), else the videos."""
        return MOTION.findall(self.page) or CLIP.findall(self.page)

    def next_page(self, status: int, text: str) -> bool | None:
        """Return True when an answer's response is the next trial (one request), False
        when it redirects (to follow), None when it was refused."""
        if status == 200 and TRIAL.search(text):
            return True
        return False if status in (301, 302) else None


class Participant(Bot):
    """A blocking bot on one kept-alive ``http.client`` connection (for tests)."""

    def __init__(self, url: str, slug: str, person: str, rng: random.Random | None = None):
        super().__init__(url, slug, person, rng)
        self.connection = None

    def request(self, method: str, path: str, data: dict | None = None, headers=None):
        """Return ``(status, location, body)``; a new connection when the server closed it."""
        sent, body = self.headers(data, headers)
        for attempt in range(2):
            if self.connection is None:
                self.connection = http.client.HTTPConnection(self.host, self.port, timeout=TIMEOUT)
            try:
                self.connection.request(method, path, body, sent)
                response = self.connection.getresponse()
                text = response.read().decode(errors="replace")
                break
            except (ConnectionError, http.client.RemoteDisconnected, http.client.BadStatusLine):
                self.close()
                if attempt or method == "POST":
                    raise
        self.keep_cookies(response.getheaders())
        if response.getheader("Connection", "").lower() == "close":
            self.close()
        return response.status, response.getheader("Location", ""), text

    def close(self):
        if self.connection is not None:
            self.connection.close()
            self.connection = None

    def get(self, path: str) -> str:
        status, location, text = self.request("GET", path)
        if status in (301, 302):
            return self.get(location)
        if status != 200:
            raise HttpError(f"GET {path}: HTTP {status}")
        self.at = path
        return text

    def post(self, path: str, data: dict) -> tuple[int, str]:
        status, location, _ = self.request("POST", path, self.form(data))
        return status, location

    def enter(self) -> None:
        self.page = self.get(self.path() + "?" + self.entry_query())

    def consent(self) -> None:
        status, location = self.post(self.path("consent"), {"agree": "1"})
        if status != 302:
            raise HttpError(f"consent: HTTP {status}")
        self.page = self.get(location)

    def start(self) -> None:
        status, location = self.post(self.path("instructions"), {})
        if status != 302:
            raise HttpError(f"instructions: HTTP {status}")
        self.page = self.get(location)

    def watch(self) -> None:
        """Fetch the page's clips whole and wait as long as they play."""
        shown = time.monotonic()
        for url in self.clips():
            status, _, _ = self.request("GET", url)
            if status != 200:
                raise HttpError(f"GET {url}: HTTP {status}")
        time.sleep(max(0.0, CLIP_SECONDS - (time.monotonic() - shown)))

    def answer(self) -> str:
        """Watch the trial on the page, submit it; return where the server sent us."""
        self.watch()
        data = self.answer_data()
        begun = time.perf_counter()
        status, location, text = self.request("POST", self.path("trial"), self.form(data))
        self.submits.append((int(data["trial"]), status, time.perf_counter() - begun))
        inline = self.next_page(status, text)
        if inline is None:
            raise HttpError(f"answer to trial {data['trial']}: HTTP {status}")
        if inline:
            self.page, location = text, self.path("trial")
        else:
            self.page = self.get(location)
        self.answer_seconds.append(time.perf_counter() - begun)
        return location



class AsyncParticipant(Bot):
    """A bot as a coroutine: one short HTTP/1.1 connection per request (gunicorn's sync
    workers close every connection), so hundreds run in one light client process."""

    async def request(self, method: str, path: str, data: dict | None = None):
        """Return ``(status, location, body)``; a clip's time to first byte is noted."""
        begun = time.perf_counter()
        sent, body = self.headers(data, {"Connection": "close"})
        payload = (body or "").encode()
        if body is not None:
            sent["Content-Length"] = str(len(payload))
        head = f"{method} {path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in sent.items())
        reader, writer = await asyncio.open_connection(self.host, self.port)
        try:
            writer.write(head.encode() + b"\r\n" + payload)
            await writer.drain()
            status_line = await reader.readline()
            if not status_line:
                raise HttpError(f"{method} {path}: the server closed the connection")
            if path.startswith("/c/"):
                self.clip_ttfb.append(time.perf_counter() - begun)
            status = int(status_line.split()[1])
            headers = []
            while (line := await reader.readline()) not in (b"\r\n", b"\n", b""):
                name, _, value = line.decode("latin-1").partition(":")
                headers.append((name.strip(), value.strip()))
            text = (await reader.read()).decode("latin-1" if path.startswith("/c/") else "utf-8",
                                                errors="replace")
        finally:
            writer.close()
        self.keep_cookies(headers)
        location = next((v for k, v in headers if k.lower() == "location"), "")
        return status, location, text

    async def get(self, path: str) -> str:
        for _ in range(5):
            status, location, text = await self.request("GET", path)
            if status not in (301, 302):
                break
            path = location
        if status != 200:
            raise HttpError(f"GET {path}: HTTP {status}")
        self.at = path
        return text

    async def step(self, name: str, data: dict) -> None:
        """POST the form of page ``name`` and follow the redirect."""
        status, location, _ = await self.request("POST", self.path(name), self.form(data))
        if status != 302:
            raise HttpError(f"{name}: HTTP {status}")
        self.page = await self.get(location)

    async def run(self, think: float = 0.0) -> None:
        """Take the whole study; wait about ``think`` seconds on every trial first."""
        self.page = await self.get(self.path() + "?" + self.entry_query())
        await self.step("consent", {"agree": "1"})
        await self.step("instructions", {})
        while self.on_trial():
            shown = time.monotonic()
            for url in self.clips():  # as a browser's media player: each clip whole
                status, _, _ = await self.request("GET", url)
                if status != 200:
                    raise HttpError(f"GET {url}: HTTP {status}")
            wait = self.rng.uniform(0.5, 1.5) * think if think else 0.0
            await asyncio.sleep(max(wait, CLIP_SECONDS) - (time.monotonic() - shown) + self.press)
            data = self.answer_data()
            begun = time.perf_counter()
            sent = time.monotonic()
            status, location, text = await self.request("POST", self.path("trial"),
                                                        self.form(data))
            self.submits.append((int(data["trial"]), status, time.perf_counter() - begun))
            inline = self.next_page(status, text)
            if inline is None:
                raise HttpError(f"answer to trial {data['trial']}: HTTP {status}")
            self.page = text if inline else await self.get(location)
            self.answer_seconds.append(time.perf_counter() - begun)
            self.answer_at.append(sent)


def make_study(slug: str, media_root: Path, actions=("walk", "wave", "jump"),
               sources=("real", "a2m", "cond_gru", "mdm"), trials: int = 6, player: str = "mp4",
               crowd: dict | None = None):
    """Create an open ranking study of tiny generated clips (3 of 4 sources per trial);
    ``player="webgl"``: each clip also has an in-page player payload of a tiny figure
    (the study plays those, the mp4 stays the fallback)."""
    from django.conf import settings

    from studyapp.survey.models import Study
    from studyapp.stimuli.clips import Clip, register_clips
    from tests.studyapp.conftest import FPS, FRAMES, write_clip

    settings.MEDIA_ROOT = media_root
    clips_dir = Path(tempfile.mkdtemp(prefix="loadtest-clips-"))
    rng = random.Random(0)
    payloads = {}
    if player == "webgl":
        from rendering import Framing
        from rendering.player import write_payloads
        from tests.rendering.conftest import make_figure

        figures = {(a, s): make_figure(frames=FRAMES, speed=0.5 + i / 8, phase=i / 3)
                   for i, (a, s) in enumerate((a, s) for a in actions for s in sources)}
        framing = Framing.from_motions(list(figures.values()))
        written = write_payloads(list(figures.values()), clips_dir / "motion", framing)
        payloads = {key: path for key, (path, _) in zip(figures, written)}
    clips = []
    for action in actions:
        for source in sources:
            path = clips_dir / f"{action}-{source}.mp4"
            write_clip(path, tuple(rng.randrange(30, 225) for _ in range(3)))
            clips.append(Clip(action, source, path, FRAMES / FPS, motion_hash=f"{action}-{source}",
                              motion=payloads.get((action, source))))
    study = Study.objects.create_study(
        "ranking", slug, "Movement study", clips_per_trial=3, trials_per_participant=trials,
        data_note="Synthetic load-test data.", player="stick" if payloads else "",
        **({"crowd": crowd} if crowd else {}),
    )
    register_clips(study, clips)
    return study


def arrival_times(n: int, over: float, seed: int = 0) -> list[float]:
    """Return when each of ``n`` participants arrives, in seconds from the launch, sorted.

    A crowd platform sends the most people at once when a study is published, fewer as
    its places fill: arrivals here are independent with a density falling linearly from
    twice the mean rate at the launch to none at ``over`` seconds (half of them arrive in
    the first 29 % of the time).
    """
    rng = random.Random(seed)
    return sorted(over * (1 - (1 - rng.random()) ** 0.5) for _ in range(n))


def check(study, acknowledged: list[int]) -> dict:
    """Compare the database with what the server acknowledged; return the figures."""
    from studyapp.survey.models import Stimulus, Trial, TrialItem

    answered = Trial.objects.filter(participant__study=study, answered_at__isnull=False)
    stored = answered.count()
    ack = Counter(acknowledged)
    duplicates = sum(n - 1 for n in ack.values() if n > 1)
    missing = set(ack) - set(answered.values_list("pk", flat=True))
    bad = 0
    ranks: dict[int, list] = {}
    rows = TrialItem.objects.filter(trial__in=answered).values_list("trial", "answers")
    for trial_id, answers in rows:
        ranks.setdefault(trial_id, []).append(answers.get("preference"))
    for values in ranks.values():
        bad += sorted(values) != list(range(1, len(values) + 1))
    per_stimulus = Counter(
        TrialItem.objects.filter(trial__in=answered, trial__kind=Trial.Kind.MAIN)
        .values_list("stimulus", flat=True)
    )
    assigned = Counter(
        TrialItem.objects.filter(trial__participant__study=study, trial__kind=Trial.Kind.MAIN)
        .values_list("stimulus", flat=True)
    )
    judged = Stimulus.objects.judged().filter(study=study)
    by_action: dict[str, list[int]] = {}
    for s in judged:
        by_action.setdefault(s.action, []).append(assigned[s.pk])
    spread = max(max(v) - min(v) for v in by_action.values())
    return {"stored": stored, "duplicates": duplicates, "missing": len(missing),
            "bad_rankings": bad, "assigned_spread": spread,
            "judged_min": min(per_stimulus.values() or [0]),
            "judged_max": max(per_stimulus.values() or [0])}


def cpu_seconds() -> tuple[float, float]:
    """Return CPU seconds used so far by the whole machine and by this process."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    busy = sum(fields) - fields[3] - fields[4]  # all but idle and iowait
    return busy / os.sysconf("SC_CLK_TCK"), time.process_time()


def cpu_by_command() -> Counter:
    """Return CPU seconds used so far by the live processes, by command name."""
    used = Counter()
    tick = os.sysconf("SC_CLK_TCK")
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue  # gone meanwhile
        name = text[text.index("(") + 1:text.rindex(")")]
        fields = text[text.rindex(")") + 2:].split()
        used[name] += (int(fields[11]) + int(fields[12])) / tick  # utime + stime
    return used


def positive_seconds(text: str) -> float:
    """Parse a number of seconds above 0 (argparse type)."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number of seconds above 0")
    return value


def windows(bots, launch: float, width: float) -> str:
    """Return the answers' p50/p99 (ms) and count per ``width`` seconds of the run, by
    when each answer was sent: where in a launch the slow answers are."""
    by_window: dict[int, list[float]] = {}
    for bot in bots:
        for at, seconds in zip(bot.answer_at, bot.answer_seconds):
            by_window.setdefault(int((at - launch) // width), []).append(1000 * seconds)
    parts = []
    for window in sorted(by_window):
        values = sorted(by_window[window])
        parts.append(f"{window * width:g}-{(window + 1) * width:g}: "
                     f"{percentile(values, 50):.0f}/{percentile(values, 99):.0f} ({len(values)})")
    return "; ".join(parts)


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    return statistics.quantiles(values, n=100, method="inclusive")[q - 1] if len(values) > 1 else values[0]


class Proxied:
    """With ``on``: Debian's nginx in front of ``server`` (``manage.py nginx_config``) and
    ``follow_fetches`` reading its clip log; otherwise the server itself."""

    def __init__(self, on: bool, env: dict, var: Path, server):
        self.on, self.env, self.var, self.server = on, env, var, server
        self.proxy = self.follower = None
        self.port = server.port

    def __enter__(self):
        if self.on:
            import subprocess

            env = dict(self.env, DJANGO_SETTINGS_MODULE="studyapp.settings")
            self.proxy = nginx(env, self.var / "nginx", f"127.0.0.1:{self.server.port}").start()
            self.follower = subprocess.Popen(
                [sys.executable, "manage.py", "follow_fetches", "--log",
                 str(self.var / "nginx" / "fetches.log")], cwd=ROOT, env=env,
                start_new_session=True)
            self.port = self.proxy.port
            # Ready when the follower has read the log once (it keeps its place beside it).
            log = self.var / "nginx" / "fetches.log"
            with open(log, "ab") as f:
                f.write(b"\n")
            until = time.monotonic() + 120
            while not log.with_name(log.name + ".offset").exists():
                if time.monotonic() > until or self.follower.poll() is not None:
                    raise RuntimeError("follow_fetches did not start")
                time.sleep(0.1)
        return self

    def __exit__(self, *exc):
        if self.follower is not None and self.follower.poll() is None:
            self.follower.terminate()
            self.follower.wait(10)
        if self.proxy is not None:
            self.proxy.stop()

    def kill(self) -> None:
        """``kill -9`` nginx and the log's follower (a node dying whole)."""
        import signal

        for process in (self.follower, self.proxy and self.proxy.process):
            if process is not None and process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(10)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--participants", type=int, default=500)
    parser.add_argument("--concurrency", type=int, default=500, help="Bots running at once.")
    parser.add_argument("--arrivals", type=int, default=0,
                        help="Participants arriving over --over seconds (an open loop, as a "
                             "crowd platform sends them); replaces --participants/--concurrency.")
    parser.add_argument("--over", type=float, default=300.0,
                        help="Seconds over which the --arrivals arrive.")
    parser.add_argument("--study", choices=("mp4", "webgl"), default="mp4",
                        help="Clips as videos, or as the in-page player's motion payloads.")
    parser.add_argument("--trials", type=int, default=6, help="Trials per participant.")
    parser.add_argument("--workers", type=int, default=(os.cpu_count() or 1) * 2 + 1)
    parser.add_argument("--think", type=float, default=0.0,
                        help="Mean seconds a bot watches each trial before answering "
                             "(0: answer at once, a closed loop measuring throughput).")
    parser.add_argument("--time-limit", type=float, default=300,
                        help="Seconds before bots give up (counted from the launch).")
    parser.add_argument("--code", type=Path, default=None,
                        help="Serve the app code of this checkout (same client and settings).")
    parser.add_argument("--nginx", action="store_true",
                        help="Serve as `make serve` does: Debian's nginx in front "
                             "(STUDY_ACCEL_REDIRECT; clips written ahead by their pages sent "
                             "by nginx) with follow_fetches beside it.")
    parser.add_argument("--crowd", choices=("none", "prolific"), default="none",
                        help="The study's crowd platform: prolific as a launch on Prolific "
                             "(its ids in the entry link, codes, the default time limit "
                             "from the study's minutes).")
    parser.add_argument("--window", type=positive_seconds, default=30.0,
                        help="Seconds per window of the answers' latency by time.")
    parser.add_argument("--keep-db", action="store_true")
    args = parser.parse_args(argv)
    if args.arrivals:
        args.participants = args.concurrency = args.arrivals
    code = (args.code or ROOT).resolve()
    if code != ROOT:
        sys.path.insert(0, str(code))  # its models and migrations, before Django loads

    name = f"loadtest_{os.getpid()}"
    var = Path(tempfile.mkdtemp(prefix="loadtest-var-"))
    url = create_database(name)
    env = server_env(url, var, STUDY_ENTRY_RATE_LIMIT="1000000/min",
                     STUDY_ENTRY_RATE_LIMIT_PER_STUDY="1000000/min")
    env["PYTHONPATH"] = str(code)
    if args.nginx:
        env.update(STUDY_ACCEL_REDIRECT="/protected-media/")
    os.environ.update({k: env[k] for k in ("DATABASE_URL", "STUDY_DATABASE_URL", "STUDY_VAR_DIR")})
    os.environ.update(DJANGO_SETTINGS_MODULE="studyapp.settings", DJANGO_DEBUG="1")
    try:
        import django
        from django.core.management import call_command

        django.setup()
        call_command("migrate", verbosity=0)
        study = make_study("load", var / "media", trials=args.trials, player=args.study,
                           crowd=PROLIFIC_CROWD if args.crowd == "prolific" else None)
        server = Server(env, workers=args.workers, settings="benchmarks.loadtest_settings",
                        log=var / "gunicorn.log", root=code)
        server.start_timeout = 180  # workers importing Django on a busy machine
        server.collectstatic()
        bots = [AsyncParticipant("http://x:1", study.slug, f"load-{i}")
                for i in range(args.participants)]
        starts = (arrival_times(args.participants, args.over) if args.arrivals
                  else [0.0] * args.participants)
        errors: list[str] = []

        async def play(bot, gate, deadline, at):
            await asyncio.sleep(max(0.0, at - (time.monotonic() - launch)))
            async with gate:
                if time.monotonic() > deadline:
                    errors.append(f"{bot.person}: time limit")
                    return
                try:
                    await asyncio.wait_for(bot.run(args.think), max(0.1, deadline - time.monotonic()))
                except Exception as exc:  # a bot's failure is a finding, not a crash
                    errors.append(f"{bot.person}: {type(exc).__name__}: {exc}")

        async def crowd():
            nonlocal launch
            gate = asyncio.Semaphore(args.concurrency)
            launch = time.monotonic()
            deadline = launch + args.time_limit
            await asyncio.gather(*(play(bot, gate, deadline, at) for bot, at in zip(bots, starts)))

        launch = 0.0
        with server, Proxied(args.nginx, env, var, server) as front:
            for bot in bots:
                bot.host, bot.port = "127.0.0.1", front.port
                bot.one_request = True
                bot.prolific = args.crowd == "prolific"
                # Behind nginx a fetch is known from its log, read every 50 ms: a bot
                # presses 200 ms after the clips' time, as a person does.
                bot.press = 0.2 if args.nginx else 0.0
            machine, client = cpu_seconds()
            by_command = cpu_by_command()
            begun = time.perf_counter()
            asyncio.run(crowd())
            elapsed = time.perf_counter() - begun
            machine_after, client_after = cpu_seconds()
            by_command = cpu_by_command() - by_command
        cores = os.cpu_count() or 1
        busy = (machine_after - machine) / (elapsed * cores)
        own = (client_after - client) / (elapsed * cores)
        submits = [s for bot in bots for s in bot.submits]
        acknowledged = [trial for trial, status, _ in submits if status in (200, 302)]
        answers = sorted(1000 * s for bot in bots for s in bot.answer_seconds)
        posts = sorted(1000 * s for _, status, s in submits if status in (200, 302))
        ttfb = sorted(1000 * s for bot in bots for s in bot.clip_ttfb)
        one = sum(1 for _, status, _ in submits if status == 200)
        figures = check(study, acknowledged)
        completed = sum(1 for bot in bots if bot.submits and not bot.on_trial())
        arrivals = f"arrivals={args.arrivals} over_s={args.over:g} " if args.arrivals else ""
        print(f"code={'this checkout' if code == ROOT else code} study={args.study} "
              f"{'behind nginx ' if args.nginx else ''}crowd={args.crowd} "
              f"participants={args.participants} {arrivals}concurrency={args.concurrency} "
              f"workers={args.workers} trials/participant={args.trials} completed={completed} "
              f"think_s={args.think:g} errors={len(errors)} elapsed_s={elapsed:.1f}")
        print(f"cpu of {cores} cores: {100 * busy:.0f}% busy, of which this client "
              f"{100 * own:.0f}%; CPU seconds by process: "
              + ", ".join(f"{name} {seconds:.1f}" for name, seconds in by_command.most_common(4)))
        for line in errors[:5]:
            print("  error:", line)
        print(f"missing={figures['missing']} bad_rankings={figures['bad_rankings']} "
              f"assigned_per_stimulus_spread={figures['assigned_spread']} "
              f"judged_per_stimulus={figures['judged_min']}..{figures['judged_max']} "
              f"answers_with_the_next_trial={one}/{len(submits)} "
              f"post_p50_ms={percentile(posts, 50):.1f} post_p99_ms={percentile(posts, 99):.1f} "
              f"clip_fetches={len(ttfb)}")
        ok = (figures["stored"] == len(acknowledged) and figures["duplicates"] == 0
              and not figures["missing"] and not figures["bad_rankings"])
        print(f"acknowledged={len(acknowledged)} stored={figures['stored']} "
              f"duplicates={figures['duplicates']} "
              f"answer_p50_ms={percentile(answers, 50):.1f} "
              f"answer_p99_ms={percentile(answers, 99):.1f} "
              f"clip_ttfb_p50_ms={percentile(ttfb, 50):.1f} "
              f"clip_ttfb_p99_ms={percentile(ttfb, 99):.1f} "
              f"answers_per_s={len(acknowledged) / elapsed:.0f}")
        print("answer p50/p99 ms by when they went (s from the launch): "
              + windows(bots, launch, args.window))
        return 0 if ok and not errors else 1
    finally:
        from django.db import connections

        connections.close_all()
        if not args.keep_db:
            drop_database(name)


if __name__ == "__main__":
    sys.exit(main())
