"""Clip fetches streamed by gunicorn, sent by nginx after the view (X-Accel-Redirect), and sent
by nginx from files their pages wrote ahead, side by side.

``.venv/bin/python benchmarks/bench_accel.py`` (docs/BENCHMARKS.md, "Clips sent by
nginx"): a fresh PostgreSQL database, a ranking study of generated mp4s grown to
``--clip-kb`` (300 kB, as a few seconds of a rendered clip), and two
servers on it with the same gunicorn workers: A streams every clip through the view (as
without ``STUDY_ACCEL_REDIRECT``), the other is the same app with ``STUDY_ACCEL_REDIRECT``
behind two nginx (``manage.py nginx_config``), each with ``follow_fetches`` beside it:
B asks the view for every clip (``--no-ahead``: it authorises the token and answers
``X-Accel-Redirect``), C sends the files the trial pages wrote ahead without asking the
app (the default). ``--participants`` bots per arm start the study (3 clips each; C's
through C, so their pages write the files); then every clip URL is fetched whole once untimed (B's
view writes its files then) and ``--rounds`` times timed, ``--concurrency`` at once,
from A, B and C in turn. Reported per arm:
time to first byte and to the last byte (p50, p99), fetches per second, CPU seconds of
gunicorn, of nginx and of the follower, and whether every clip was recorded as fetched
whole (B, C: from nginx's log; A: by the view; each arm fetches the clips of
participants of its own).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.loadtest import AsyncParticipant, cpu_by_command, make_study, percentile  # noqa: E402
from benchmarks.server import Server, create_database, drop_database, nginx, server_env  # noqa: E402


def pad_clips(study, size: int) -> None:
    """Grow the study's stored mp4s to ``size`` bytes with a trailing ``free`` box (still
    valid mp4s), so the bytes sent weigh as a real clip's do."""
    import struct

    from django.core.files.storage import default_storage

    for name in study.stimuli.values_list("video", flat=True):
        path = Path(default_storage.path(name))
        extra = size - path.stat().st_size
        if extra > 8:
            with open(path, "ab") as f:
                f.write(struct.pack(">I", extra) + b"free" + bytes(extra - 8))


def cpu_of(pid: int) -> float:
    """CPU seconds used so far by process ``pid``."""
    text = Path(f"/proc/{pid}/stat").read_text()
    fields = text[text.rindex(")") + 2:].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


async def fetch(port: int, path: str) -> tuple[float, float, int]:
    """GET ``path`` whole; return (seconds to the first byte, to the last, bytes)."""
    begun = time.perf_counter()
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n".encode())
        await writer.drain()
        first = await reader.read(1)
        ttfb = time.perf_counter() - begun
        rest = await reader.read()
    finally:
        writer.close()
    return ttfb, time.perf_counter() - begun, len(first) + len(rest)


async def fetch_all(port: int, paths: list[str], concurrency: int):
    gate = asyncio.Semaphore(concurrency)

    async def one(path):
        async with gate:
            return await fetch(port, path)

    return await asyncio.gather(*(one(p) for p in paths))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--participants", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--concurrency", type=int, default=100)
    parser.add_argument("--workers", type=int, default=3)
    parser.add_argument("--clip-kb", type=int, default=300,
                        help="Stored clips grown to this size (0: the tiny generated ones).")
    args = parser.parse_args(argv)

    name = f"bench_accel_{os.getpid()}"
    var = Path(tempfile.mkdtemp(prefix="bench-accel-"))
    url = create_database(name)
    os.environ.update(DATABASE_URL=url, STUDY_DATABASE_URL=url, STUDY_VAR_DIR=str(var),
                      DJANGO_SETTINGS_MODULE="studyapp.settings", DJANGO_DEBUG="1")
    servers, proxies, followers = [], {}, {}
    try:
        import django
        from django.core.management import call_command

        django.setup()
        call_command("migrate", verbosity=0)
        study = make_study("accel", var / "media", trials=2)
        if args.clip_kb:
            pad_clips(study, args.clip_kb * 1024)
        env = server_env(url, var, STUDY_ENTRY_RATE_LIMIT="1000000/min",
                         STUDY_ENTRY_RATE_LIMIT_PER_STUDY="1000000/min",
                         STUDY_CACHE_URL="", STUDY_FETCH_LOG_URL="")
        streamed = Server(env, workers=args.workers, settings="benchmarks.loadtest_settings",
                          log=var / "streamed.log")
        accel_env = dict(env, STUDY_ACCEL_REDIRECT="/protected-media/")
        accel = Server(accel_env, workers=args.workers, settings="benchmarks.loadtest_settings",
                       log=var / "accel.log")
        streamed.collectstatic()
        servers = [streamed.start(timeout=180), accel.start(timeout=180)]
        nginx_env = dict(accel_env, DJANGO_SETTINGS_MODULE="studyapp.settings")
        proxies = {"nginx after the view": nginx(nginx_env, var / "nginx-view",
                                                 f"127.0.0.1:{accel.port}", ahead=False).start(),
                   "nginx, written ahead": nginx(nginx_env, var / "nginx-ahead",
                                                 f"127.0.0.1:{accel.port}").start()}
        followers = {label: subprocess.Popen(
            [sys.executable, "manage.py", "follow_fetches", "--log",
             str(Path(p.log).parent / "fetches.log")],
            cwd=ROOT, env=nginx_env, start_new_session=True) for label, p in proxies.items()}

        half = args.participants  # each arm's own deliveries: its records are its own
        arms = {"gunicorn streams": streamed.url, **{k: p.url for k, p in proxies.items()}}
        ports = {"gunicorn streams": streamed.port, **{k: p.port for k, p in proxies.items()}}
        # A's and B's pages come from the server that writes nothing ahead; C's from C.
        entry = {"gunicorn streams": streamed.url, "nginx after the view": streamed.url,
                 "nginx, written ahead": arms["nginx, written ahead"]}
        bots = {label: [AsyncParticipant(entry[label], study.slug, f"accel-{k}-{i}")
                        for i in range(half)] for k, label in enumerate(arms)}

        async def start_all():
            gate = asyncio.Semaphore(20)

            async def one(bot):
                async with gate:
                    bot.page = await bot.get(bot.path() + "?PROLIFIC_PID=" + bot.person)
                    await bot.step("consent", {"agree": "1"})
                    await bot.step("instructions", {})

            await asyncio.gather(*(one(b) for group in bots.values() for b in group))

        asyncio.run(start_all())
        paths = {label: [p for bot in group for p in bot.clips()] for label, group in bots.items()}
        results = {label: [] for label in arms}
        cpu = {label: 0.0 for label in arms}
        nginx_cpu = {label: 0.0 for label in arms}
        follow_cpu = {label: 0.0 for label in arms}
        elapsed = {label: 0.0 for label in arms}
        # One untimed round first: B's view writes its deliveries' files then (as C's pages
        # did before), so the timed rounds compare sending, not writing.
        for label in arms:
            asyncio.run(fetch_all(ports[label], paths[label], args.concurrency))
        for _ in range(args.rounds):
            for label in arms:
                follower = followers.get(label)
                before = cpu_by_command()
                follow_before = cpu_of(follower.pid) if follower else 0.0
                begun = time.perf_counter()
                results[label] += asyncio.run(fetch_all(ports[label], paths[label], args.concurrency))
                elapsed[label] += time.perf_counter() - begun
                used = cpu_by_command() - before
                cpu[label] += used.get("gunicorn", 0.0)
                if follower:
                    nginx_cpu[label] += used.get("nginx", 0.0)
                    follow_cpu[label] += cpu_of(follower.pid) - follow_before
        from studyapp.participation import fetch_log
        from studyapp.survey.models import TrialItem

        def recorded():
            fetch_log.flush()
            out = {}
            for label, some in paths.items():
                tokens = {Path(p).stem for p in some}
                out[label] = (TrialItem.objects.filter(token__in=tokens, fetched_at__isnull=False)
                              .count(), len(tokens))
            return out

        until = time.monotonic() + 30  # the follower's last lines (it may start late)
        whole = recorded()
        while any(w < n for w, n in whole.values()) and time.monotonic() < until:
            time.sleep(0.5)
            whole = recorded()
        print(f"{len(paths['gunicorn streams'])} clips of {args.clip_kb} kB an arm "
              f"({args.participants} participants x 3), "
              f"each fetched whole once untimed, then {args.rounds} times, {args.concurrency} at once; "
              f"{args.workers} gunicorn workers a server")
        base = None
        for label, rows in results.items():
            ttfb = sorted(r[0] * 1000 for r in rows)
            total = sorted(r[1] * 1000 for r in rows)
            rate = len(rows) / elapsed[label]
            base = base or rate
            extra = (f", nginx {nginx_cpu[label]:.1f} s, follow_fetches {follow_cpu[label]:.1f} s"
                     if label in followers else "")
            print(f"{label}: ttfb p50 {percentile(ttfb, 50):.1f} ms p99 {percentile(ttfb, 99):.1f} ms; "
                  f"whole p50 {percentile(total, 50):.1f} ms p99 {percentile(total, 99):.1f} ms; "
                  f"{rate:.0f} fetches/s ({rate / base:.2f}x); CPU gunicorn {cpu[label]:.1f} s{extra}; "
                  f"recorded whole {whole[label][0]}/{whole[label][1]}")
        return 0
    finally:
        for follower in followers.values():
            follower.terminate()
            follower.wait(10)
        for proxy in proxies.values():
            proxy.stop()
        for server in servers:
            server.stop()
        from django.db import connections

        connections.close_all()
        drop_database(name)


if __name__ == "__main__":
    sys.exit(main())
