"""Two app nodes behind a real HAProxy, one PostgreSQL, one Redis; one node killed mid-study.

``.venv/bin/python benchmarks/nodes.py --participants 500`` (docs/BENCHMARKS.md, "Many
nodes"): creates a fresh PostgreSQL database and a ranking study of tiny generated mp4s
(3 sources, all three in every trial: balance allows a spread of 1), starts two gunicorn
nodes (production settings, ``STUDY_NODES=2``, each with a fetch spool of its own that
nothing reads: witnesses and rate limits are in the one Redis) on 127.0.0.1, and Debian's
HAProxy in front of them (round robin, a node checked by connecting every 0.5 s). Bot participants
take the study through HAProxy (every clip fetched whole); once ``--kill-at`` of the
answers are in, one node is killed (``kill -9``, master and workers). Bots cut off come
back with their cookies, as people press reload, and finish on the other node.

Then it checks the database: every participant stored once and complete, every trial
answered once with a whole ranking, every acknowledged answer stored, the stimuli's
seats balanced (spread 1), and the per-study consent limit of ``--limit`` counted once
for both nodes: of ``--limit + 20`` consents to a second study from one address exactly
``--limit`` pass. The last line is ``participants=N nodes=2 killed=1 ... ok=True``.

``--nginx``: each node is what ``make serve`` starts on a machine, Debian's nginx in front
of its gunicorn (clips written ahead, sent by nginx, ``follow_fetches`` reading its log into
Redis), and HAProxy balances over the two nginx; the kill takes the whole node (nginx, its
log's follower, gunicorn).

The test (tests/studyapp/test_nodes.py) runs the same with a few dozen bots, with and
without ``--nginx``.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import random
import socket
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from urllib.parse import urlencode

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.loadtest import (  # noqa: E402
    AsyncParticipant, Proxied, check, make_study, percentile)
from benchmarks.server import (  # noqa: E402
    Server, create_database, drop_database, haproxy, server_env)

SOURCES = ("real", "a2m", "mdm")


def redis_url() -> str:
    """A Redis database of its own for this run (emptied first)."""
    import redis

    url = f"redis://127.0.0.1:6379/{8 + os.getpid() % 8}"
    redis.Redis.from_url(url).flushdb()
    return url


def served_by(socket_path: Path) -> dict[str, int]:
    """Return the sessions HAProxy sent to each node (its stats socket)."""
    with socket.socket(socket.AF_UNIX) as s:
        s.connect(str(socket_path))
        s.sendall(b"show stat\n")
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    lines = data.decode().splitlines()
    header = lines[0].lstrip("# ").split(",")
    out = {}
    for line in lines[1:]:
        row = dict(zip(header, line.split(",")))
        if row.get("pxname") == "nodes" and row.get("svname", "").startswith("node"):
            out[row["svname"]] = int(row["stot"] or 0)
    return out


async def limited_consents(url: str, slug: str, count: int, at_once: int = 50) -> Counter:
    """``count`` people from one address open a study and consent (``at_once`` at a
    time); return the consents' statuses ("error" for a request that failed before)."""
    gate = asyncio.Semaphore(at_once)

    async def one(i):
        async with gate:
            bot = AsyncParticipant(url, slug, f"limited-{i}")
            try:
                bot.page = await bot.get(bot.path() + "?" + urlencode({"PROLIFIC_PID": f"limited-{i}"}))
                status, _, _ = await bot.request("POST", bot.path("consent"), bot.form({"agree": "1"}))
            except Exception:
                return "error"
            return status

    return Counter(await asyncio.gather(*(one(i) for i in range(count))))


def run(database_url: str, var: Path, participants: int, trials: int = 4, workers: int = 2,
        kill_at: float = 0.4, limit: int | None = None, concurrency: int | None = None,
        time_limit: float = 600, secret_key: str | None = None, think: float = 0.0,
        retries: int = 5, behind_nginx: bool = False) -> dict:
    """Run the study on two nodes, kill one; return the figures (``ok``: every check held).

    The database must be migrated and Django set up in this process (it reads the
    results and creates the studies).
    """
    from studyapp.survey.models import Participant as Row
    from studyapp.survey.models import Trial, TrialItem

    limit = limit or 3 * participants  # the main study (retries consent again) never reaches it
    study = make_study(f"nodes-{os.getpid()}", var / "media", sources=SOURCES, trials=trials)
    limited = make_study(f"limited-{os.getpid()}", var / "media", sources=SOURCES, trials=1)
    cache = redis_url()
    base = server_env(database_url, var, STUDY_NODES="2", STUDY_CACHE_URL=cache,
                      STUDY_FETCH_LOG_URL=cache, STUDY_FETCH_FLUSH_S="2",
                      STUDY_ENTRY_RATE_LIMIT="1000000/min",
                      STUDY_ENTRY_RATE_LIMIT_PER_STUDY=f"{limit}/h")
    if secret_key:
        base["DJANGO_SECRET_KEY"] = secret_key
    if behind_nginx:
        base["STUDY_ACCEL_REDIRECT"] = "/protected-media/"
    envs = [dict(base, STUDY_FETCH_SPOOL=str(var / f"spool-{i}")) for i in range(2)]
    nodes = [Server(env, workers=workers, settings="benchmarks.loadtest_settings",
                    log=var / f"node{i}.log") for i, env in enumerate(envs)]
    fronts = [Proxied(behind_nginx, env, var / f"node{i}", node)
              for i, (env, node) in enumerate(zip(envs, nodes))]
    nodes[0].collectstatic()
    bots = [AsyncParticipant("http://x:1", study.slug, f"node-bot-{i}", random.Random(i))
            for i in range(participants)]
    errors: list[str] = []
    expected = participants * trials
    balancer = None
    try:
        for node, front in zip(nodes, fronts):
            node.start(timeout=180)  # Django's start takes long on a busy machine
            front.__enter__()
        balancer = haproxy(var / "haproxy", [f"127.0.0.1:{front.port}" for front in fronts])
        stats = var / "haproxy" / "stats.sock"
        config = balancer.command[-1]
        Path(config).write_text(Path(config).read_text().replace(
            "global\n", f"global\n    stats socket {stats} mode 600 level admin\n"))
        balancer.start()
        for bot in bots:
            bot.host, bot.port = "127.0.0.1", balancer.port
            # Behind nginx a fetch is known from its log (read every 50 ms): press 0.2 s
            # after the clips' time, as a person does.
            bot.press = 0.2 if behind_nginx else 0.0

        async def crowd(which):
            gate = asyncio.Semaphore(concurrency or len(which))

            async def play(bot):
                async with gate:
                    try:
                        await asyncio.wait_for(bot.run(think), time_limit)
                        return None
                    except Exception as exc:
                        return bot, exc

            return [r for r in await asyncio.gather(*(play(b) for b in which)) if r]

        def acknowledged():
            return [t for bot in bots for t, status, _ in bot.submits if status == 302]

        cut_off = []
        begun = time.perf_counter()
        first = threading.Thread(target=lambda: cut_off.extend(asyncio.run(crowd(bots))))
        first.start()
        deadline = time.monotonic() + time_limit
        while (len(acknowledged()) < kill_at * expected and first.is_alive()
               and time.monotonic() < deadline):
            time.sleep(0.01)
        killed_at = len(acknowledged())
        nodes[0].kill()
        fronts[0].kill()
        first.join(time_limit)
        again, rounds = list(cut_off), 0
        while again and rounds < retries:  # they come back with their cookies, as people
            rounds += 1                   # press reload, and finish on the other node
            errors.extend(f"{bot.person}: {type(exc).__name__}: {exc}" for bot, exc in again)
            left = []
            retry = threading.Thread(
                target=lambda: left.extend(asyncio.run(crowd([b for b, _ in again]))))
            retry.start()
            retry.join(time_limit)
            again = left
        elapsed = time.perf_counter() - begun
        consents = Counter()
        consenting = threading.Thread(target=lambda: consents.update(
            asyncio.run(limited_consents(balancer.url, limited.slug, limit + 20))))
        consenting.start()
        consenting.join(time_limit)
        served = served_by(stats)
    finally:
        if balancer is not None:
            balancer.stop()
        for node, front in zip(nodes, fronts):
            front.__exit__(None, None, None)
            node.stop()

    acks = acknowledged()
    figures = check(study, acks)
    rows = Row.objects.filter(study=study)
    trials_all = Trial.objects.filter(participant__study=study)
    people = Counter(rows.values_list("external_key", flat=True))
    latencies = sorted(s * 1000 for bot in bots for _, status, s in bot.submits if status == 302)
    result = {
        "participants": participants, "stored_participants": rows.count(),
        "participants_twice": sum(n > 1 for n in people.values()),
        "completed": rows.filter(completed_at__isnull=False).count(),
        "trials": trials_all.count(),
        "answered": trials_all.filter(answered_at__isnull=False).count(),
        "items": TrialItem.objects.filter(trial__participant__study=study).count(),
        "acknowledged": len(acks), "killed_at": killed_at, "cut_off": len(cut_off),
        "still_failing": len(again), "retry_rounds": rounds,
        "cut_off_by": dict(Counter(str(exc).rsplit(" ", 1)[-1] for _, exc in cut_off)), "served_by": served,
        "limited_passed": consents.get(302, 0), "limited_refused": consents.get(429, 0),
        "limited_errors": consents.get("error", 0),
        "limit": limit, "elapsed_s": elapsed,
        "p50_ms": percentile(latencies, 50), "p99_ms": percentile(latencies, 99),
        **figures,
    }
    result["ok"] = bool(
        result["stored_participants"] == participants and not result["participants_twice"]
        and result["completed"] == participants
        and result["answered"] == result["trials"] == participants * trials_per(study)
        and result["items"] == result["trials"] * 3
        and not figures["missing"] and not figures["duplicates"] and not figures["bad_rankings"]
        and figures["assigned_spread"] <= 1 and not again
        and result["limited_passed"] == limit
        and result["limited_refused"] == 20
        and all(served.get(f"node{i}", 0) > 0 for i in range(2)))
    result["errors"] = errors + [f"again {bot.person}: {type(exc).__name__}: {exc}"
                                 for bot, exc in again]
    return result


def trials_per(study) -> int:
    from studyapp.survey.models import Study

    return Study.objects.get(pk=study.pk).trials_per_participant


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--participants", type=int, default=500)
    parser.add_argument("--trials", type=int, default=4)
    parser.add_argument("--workers", type=int, default=3, help="gunicorn workers per node.")
    parser.add_argument("--think", type=float, default=0.0,
                        help="Mean seconds a bot watches each trial (0: a closed loop).")
    parser.add_argument("--kill-at", type=float, default=0.4,
                        help="Kill node 0 once this share of the answers is in.")
    parser.add_argument("--time-limit", type=float, default=600)
    parser.add_argument("--nginx", action="store_true",
                        help="Each node behind its own nginx, as `make serve` runs it.")
    parser.add_argument("--keep-db", action="store_true")
    args = parser.parse_args(argv)

    name = f"nodes_{os.getpid()}"
    var = Path(tempfile.mkdtemp(prefix="nodes-var-"))
    url = create_database(name)
    os.environ.update(DATABASE_URL=url, STUDY_DATABASE_URL=url, STUDY_VAR_DIR=str(var),
                      DJANGO_SETTINGS_MODULE="studyapp.settings", DJANGO_DEBUG="1")
    try:
        import django
        from django.core.management import call_command

        django.setup()
        call_command("migrate", verbosity=0)
        r = run(url, var, args.participants, args.trials, args.workers, args.kill_at,
                time_limit=args.time_limit, think=args.think, behind_nginx=args.nginx)
        for line in r["errors"][:3]:
            print("  cut off:", line)
        print(f"served by node: {r['served_by']}; killed node0 after {r['killed_at']} "
              f"of {r['participants'] * args.trials} answers; {r['cut_off']} bots cut off "
              f"(by {r['cut_off_by']}) came back ({r['retry_rounds']} rounds, "
              f"{r['still_failing']} still failing); elapsed_s={r['elapsed_s']:.1f}")
        print(f"consents to a study limited to {r['limit']}/h from one address, through "
              f"both nodes: {r['limited_passed']} passed, {r['limited_refused']} refused")
        print(f"participants={r['participants']} stored={r['stored_participants']} "
              f"stored_twice={r['participants_twice']} completed={r['completed']} "
              f"trials={r['trials']} answered={r['answered']} acknowledged={r['acknowledged']} "
              f"missing={r['missing']} duplicates={r['duplicates']} "
              f"bad_rankings={r['bad_rankings']} assigned_spread={r['assigned_spread']} "
              f"p50_ms={r['p50_ms']:.0f} p99_ms={r['p99_ms']:.0f} ok={r['ok']}")
        return 0 if r["ok"] else 1
    finally:
        from django.db import connections

        connections.close_all()
        if not args.keep_db:
            drop_database(name)


if __name__ == "__main__":
    sys.exit(main())
