"""Clip fetches streamed by gunicorn against sent by nginx (X-Accel-Redirect), side by side.

``.venv/bin/python benchmarks/bench_accel.py`` (docs/BENCHMARKS.md, "Clips sent by
nginx"): a fresh PostgreSQL database, a ranking study of generated mp4s grown to
``--clip-kb`` (300 kB, as a few seconds of a rendered clip), and two
servers on it with the same gunicorn workers: A streams every clip through the view (as
without ``STUDY_ACCEL_REDIRECT``), B is the same app with ``STUDY_ACCEL_REDIRECT`` behind
nginx (``manage.py nginx_config``) with ``follow_fetches`` beside it. ``--participants``
bots start the study (3 clips each); then every clip URL is fetched whole ``--rounds``
times, ``--concurrency`` at once, from A and from B in turn (A, B, A, B, ...). Reported
per server: time to first byte and to the last byte (p50, p99), fetches per second, CPU
seconds of gunicorn, of nginx and of the follower, and whether every clip was recorded
as fetched whole (B: from nginx's log; A: by the view; each server fetches the clips
of participants of its own).
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
    servers, proxy, follower = [], None, None
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
        proxy = nginx(dict(accel_env, DJANGO_SETTINGS_MODULE="studyapp.settings"),
                      var / "nginx", f"127.0.0.1:{accel.port}").start()
        follower = subprocess.Popen(
            [sys.executable, "manage.py", "follow_fetches", "--log", str(var / "nginx" / "fetches.log")],
            cwd=ROOT, env=dict(accel_env, DJANGO_SETTINGS_MODULE="studyapp.settings"),
            start_new_session=True)

        bots = [AsyncParticipant(streamed.url, study.slug, f"accel-{i}")
                for i in range(2 * args.participants)]

        async def start_all():
            gate = asyncio.Semaphore(20)

            async def one(bot):
                async with gate:
                    bot.page = await bot.get(bot.path() + "?PROLIFIC_PID=" + bot.person)
                    await bot.step("consent", {"agree": "1"})
                    await bot.step("instructions", {})

            await asyncio.gather(*(one(b) for b in bots))

        asyncio.run(start_all())
        half = args.participants  # each server's own deliveries: its records are its own
        paths = {"gunicorn streams": [p for bot in bots[:half] for p in bot.clips()],
                 "nginx sends": [p for bot in bots[half:] for p in bot.clips()]}
        results = {"gunicorn streams": [], "nginx sends": []}
        cpu = {"gunicorn streams": 0.0, "nginx sends": 0.0}
        nginx_cpu = follow_cpu = 0.0
        elapsed = {"gunicorn streams": 0.0, "nginx sends": 0.0}
        for _ in range(args.rounds):
            for label, port, _ in (("gunicorn streams", streamed.port, streamed),
                                      ("nginx sends", proxy.port, accel)):
                before, follow_before = cpu_by_command(), cpu_of(follower.pid)
                begun = time.perf_counter()
                results[label] += asyncio.run(fetch_all(port, paths[label], args.concurrency))
                elapsed[label] += time.perf_counter() - begun
                used = cpu_by_command() - before
                cpu[label] += used.get("gunicorn", 0.0)
                if label == "nginx sends":
                    nginx_cpu += used.get("nginx", 0.0)
                    follow_cpu += cpu_of(follower.pid) - follow_before
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
        while (whole := recorded())["nginx sends"][0] < len(paths["nginx sends"]) and (
                time.monotonic() < until):
            time.sleep(0.5)
        print(f"{len(paths['nginx sends'])} clips of {args.clip_kb} kB a server "
              f"({args.participants} participants x 3), "
              f"each fetched whole {args.rounds} times, {args.concurrency} at once; "
              f"{args.workers} gunicorn workers a server")
        base = None
        for label, rows in results.items():
            ttfb = sorted(r[0] * 1000 for r in rows)
            total = sorted(r[1] * 1000 for r in rows)
            rate = len(rows) / elapsed[label]
            base = base or rate
            extra = (f", nginx {nginx_cpu:.1f} s, follow_fetches {follow_cpu:.1f} s"
                     if label == "nginx sends" else "")
            print(f"{label}: ttfb p50 {percentile(ttfb, 50):.1f} ms p99 {percentile(ttfb, 99):.1f} ms; "
                  f"whole p50 {percentile(total, 50):.1f} ms p99 {percentile(total, 99):.1f} ms; "
                  f"{rate:.0f} fetches/s ({rate / base:.2f}x); CPU gunicorn {cpu[label]:.1f} s{extra}; "
                  f"recorded whole {whole[label][0]}/{whole[label][1]}")
        return 0
    finally:
        if follower is not None:
            follower.terminate()
            follower.wait(10)
        if proxy is not None:
            proxy.stop()
        for server in servers:
            server.stop()
        from django.db import connections

        connections.close_all()
        drop_database(name)


if __name__ == "__main__":
    sys.exit(main())
