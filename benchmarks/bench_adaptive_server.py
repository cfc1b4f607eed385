"""Adaptive against balanced with the real server: judgements to a target interval width.

    nice -n 10 .venv/bin/python benchmarks/bench_adaptive_server.py [--studies 3]
        [--target top_two|order] [--width 1.2] [--clips 6] [--clip-sd 0.3] [--trials 10]
        [--every 25] [--batch N] [--concurrency 6] [--parallel 1] [--workers 3]
        [--budget 3000] [--time-limit 900] [--database postgres|sqlite] [--db-name NAME]
        [--first-seed 1000] [--bootstrap 1000] [--json out.json]
    .venv/bin/python benchmarks/bench_adaptive_server.py --summarise out.json

The same comparison as ``benchmarks/bench_adaptive.py`` (docs/BENCHMARKS.md, "Adaptive
designs"), but nothing is simulated below the HTTP pages: a fresh database (PostgreSQL on
127.0.0.1, a database of its own, dropped at the end; or SQLite in the run's folder),
gunicorn with the production settings on 127.0.0.1 (``benchmarks/server.py``), and per
replicate two pairwise studies of the same clips, one ``design: adaptive`` and one
``design: balanced``, both with ``adaptive: {every, target}`` (and ``batch`` with
``--batch N``: each look's next ``N`` comparisons planned as one batch, the simulation's
``order_batch`` with ``--target order``; without it the app's default: a batch of
``every`` for ``target: order``, none for ``top_two``) and ``stop_when: {interval_width:
W}``, taken at the same time by bots of known strengths. ``--parallel K`` runs ``K`` replicates at once
(each still its two studies at the same time with the same settings; a new replicate
starts when one ends), so that many replicates fit in the time: the answers a second of
the whole run are printed at the end, to choose ``--concurrency``, ``--parallel`` and
``--workers`` for a machine (a short run first). The PostgreSQL database is named
``--db-name`` (default ``bench_adaptive_srv_<pid>``).

- Sources: 8, log strengths :data:`benchmarks.bench_adaptive.STRENGTHS` (1.6, 1.3, 1.0,
  0.8, 0.5, 0.2, -0.3, -1.0; the top two 0.3 apart), ``--clips`` clips each (tiny
  generated mp4s of 0.4 s, one action: the cheapest clips the app serves).
- Bots: the ``bt`` policy of ``simulate_participants`` (``participation.bots``, through
  the real pages: every clip fetched whole, the clips' time waited, as the server's watch
  rule asks), each clip's quality its source's log strength plus a fixed normal draw
  (``--clip-sd``, :func:`studyapp.participation.bots.clip_effect`: from the clip's
  stimulus id and the replicate's seed). The two studies of a replicate hold the same
  files but as stimuli of their own, so their clips' draws are independent: the designs
  are compared over the same distribution of clips, not the same clips. ``--concurrency``
  bots per study at once; new ones start until the study has stopped. BLAS runs on one
  thread (``OPENBLAS_NUM_THREADS=1`` unless set, here and in the server: many small
  products on a shared machine run slower on several).
- The design and the stop run as in production: when a participant starts and ``every``
  main trials were answered since the last look, the server starts the ``adaptive_design``
  job in the background (a thread of the gunicorn worker: no Celery broker here), which
  stores the distribution and checks the rule; met, the study closes (``Study.stopped``).
  Bots already taking part finish, and their answers count, as people's would.
- Measured per study: the judgements at the stop (``Study.stopped["judgements"]``) and at
  the end (every answer stored), and the report's own intervals: the pairwise analysis of
  the exported responses (``analysis.study.analyse``: Bradley-Terry with the crossed
  bootstrap of participants and clips, ``--bootstrap`` replicates), for the target's pairs
  in the report's estimated order (the top two, or every neighbour). Their width and
  whether they cover the true difference, of two truths: ``population``, the balanced
  Bradley-Terry difference of infinitely many clips and judgements
  (:func:`benchmarks.bench_adaptive.truth`: the estimand of intervals that count clips as
  random, and the truth bench_adaptive uses) and ``these clips``, the same of the study's
  own clips (their mean clip effects included).

The run is bounded: a study stops at ``--budget`` answered main trials or after
``--time-limit`` seconds, whichever comes first (then it counts as not reached), and the
server is stopped, and its database and folder removed, at the end whatever happens. The last lines are a Markdown table
(:func:`table`); ``--summarise out.json`` prints it again from a run's ``--json`` file.
``tests/studyapp/test_bench_adaptive_server.py`` runs :func:`run_pair` at a tiny size
(against the test live server, in-process).
"""

from __future__ import annotations

import argparse
import http.cookiejar
import json
import os
import random
import shutil
import sys
import tempfile
import threading
import time
import urllib.request
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, as_completed, wait
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: see the docstring

import numpy as np  # noqa: E402
from scipy.special import expit  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.bench_adaptive import STRENGTHS, truth  # noqa: E402

SOURCES = tuple(f"m{i}" for i in range(1, len(STRENGTHS) + 1))
DESIGNS = ("adaptive", "balanced")


def browser_opener(bot) -> urllib.request.OpenerDirector:
    """Return ``bot``'s opener with a cookie jar that sends Secure cookies over plain
    HTTP: the production settings mark the session and CSRF cookies Secure, and this
    server has no TLS in front of it (as ``benchmarks/loadtest.py``'s bots keep cookies
    by hand for the same reason)."""
    policy = http.cookiejar.DefaultCookiePolicy(secure_protocols=("https", "wss", "http"))
    opener = urllib.request.build_opener(
        urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar(policy)))
    opener.addheaders = list(bot.opener.addheaders)
    return opener


def write_clips(folder: Path, clips: int, seed: int = 0) -> list:
    """Write ``clips`` tiny mp4s per source (each its own colour) and return them as
    :class:`~studyapp.stimuli.clips.Clip` of the one action ``walk``."""
    from studyapp.stimuli.clips import Clip
    from tests.studyapp.conftest import FPS, FRAMES, write_clip

    folder.mkdir(parents=True, exist_ok=True)
    rng = random.Random(seed)
    out = []
    for source in SOURCES:
        for k in range(clips):
            path = folder / f"walk-{source}-{k}.mp4"
            write_clip(path, tuple(rng.randrange(30, 225) for _ in range(3)))
            out.append(Clip("walk", source, path, FRAMES / FPS, motion_hash=f"walk-{source}-{k}"))
    return out


class _Prefers(Exception):
    pass


def choice_type() -> str:
    """Return the study type of pairs whose bots answer by preferring one clip of the two
    (``Policy.prefer``: the Bradley-Terry choice itself), asked of the registry: no file
    outside a type names its key (tests/test_plugins.py)."""
    from studyapp.participation.adaptive import model
    from studyapp.participation.bots import Policy, TrialPage
    from studyapp.survey.study_types import get_study_type, list_study_types

    class Probe(Policy):
        def prefer(self, left, right, ties):
            raise _Prefers

    page = TrialPage({}, ["a", "b"], ["left", "right"], sources={"a": "x", "b": "y"})
    for name in list_study_types():
        if model(name) != "pairs":
            continue
        try:
            get_study_type(name).bot_answer(page, Probe(random.Random(0)))
        except _Prefers:
            return name
        except Exception:  # a type of pairs answered otherwise (a graded scale)
            continue
    raise RuntimeError("no study type of pairs answered by a preference is registered")


def make_study(slug: str, design: str, clips: list, target: str, width: float,
               trials: int, every: int, batch: int | None = None):
    """Create an open study of pairs (:func:`choice_type`) of ``clips`` with the design and
    stopping rule (``batch``: ``adaptive.batch``, left out when None: the app's default)."""
    from studyapp.survey.models import Study
    from studyapp.stimuli.clips import register_clips

    settings = {"every": every, "target": target, **({"batch": batch} if batch is not None else {})}
    study = Study.objects.create_study(
        choice_type(), slug, "Movement study", clips_per_trial=2, trials_per_participant=trials,
        design=design, adaptive=settings,
        stop_when={"interval_width": width}, data_note="Synthetic benchmark data (bots).")
    register_clips(study, clips)
    return study


def take_part(study, url: str, seed: int, clip_sd: float, concurrency: int, budget: int,
              time_limit: float) -> dict:
    """Send bots of known strengths to ``study`` on ``url`` until it has stopped (or the
    budget or time is spent); wait for those taking part to finish. Return the counts."""
    from django.db import close_old_connections

    from studyapp.participation.adaptive import answered_main
    from studyapp.participation.bots import (POLICIES, Bot, SimulationError, entry_url,
                                             person_id)
    from studyapp.survey.models import Study

    strengths = {name: float(np.exp(s)) for name, s in zip(SOURCES, STRENGTHS)}
    errors, started = [], 0
    lock = threading.Lock()

    def one(i):
        rng = random.Random(f"{seed}-{study.slug}-{i}")
        policy = POLICIES.get("bt")(rng, strengths, SOURCES, clip_sd=clip_sd, clip_seed=seed)
        bot = Bot(study, policy, rng)
        bot.opener = browser_opener(bot)
        try:
            bot.run(entry_url(study, url, person_id(f"{study.slug}-{seed}", i)))
        except SimulationError as error:
            with lock:
                errors.append(str(error))
        finally:
            close_old_connections()

    begun = time.monotonic()
    reason = "time"
    with ThreadPoolExecutor(max_workers=concurrency) as pool:
        running = set()
        while time.monotonic() - begun < time_limit:
            if Study.objects.filter(pk=study.pk).values_list("stopped", flat=True).first():
                reason = "stopped"
                break
            answered = answered_main(study)
            if answered >= budget:
                reason = "budget"
                break
            if not answered and len(errors) >= 2 * concurrency:
                reason = "failing"
                break
            while len(running) < concurrency:
                running.add(pool.submit(one, started))
                started += 1
            _, running = wait(running, timeout=0.5, return_when=FIRST_COMPLETED)
        wait(running)
    close_old_connections()
    return {"participants": started, "errors": errors, "ended_by": reason,
            "seconds": time.monotonic() - begun}


def clip_qualities(study, clip_sd: float, seed: int) -> dict[str, list[float]]:
    """Return per source the qualities (log strengths) of the study's judged clips, as the
    bots see them."""
    from studyapp.participation.bots import clip_effect
    from studyapp.survey.models import Stimulus

    base = dict(zip(SOURCES, STRENGTHS))
    out = {name: [] for name in SOURCES}
    for pk, source in Stimulus.objects.judged().filter(study=study).values_list("pk", "source"):
        out[source].append(base[source] + clip_effect(pk, clip_sd, seed))
    return out


def these_clips_truth(qualities: dict[str, list[float]]) -> np.ndarray:
    """Return the centred Bradley-Terry worths of infinitely many balanced judgements of
    exactly these clips (every pair of clips of two sources alike)."""
    from analysis import worth

    orders, counts = [], []
    for i, a in enumerate(SOURCES):
        for j, b in enumerate(SOURCES):
            if i != j:
                qa, qb = np.array(qualities[a]), np.array(qualities[b])
                orders.append([i, j])
                counts.append(expit(qa[:, None] - qb[None, :]).mean() * 1e6)
    return worth.fit(np.array(orders), np.array(counts), len(SOURCES), prior=0)


def report_intervals(study, target: str, bootstrap: int, seed: int) -> list[dict]:
    """Return the report's differences for the target's pairs, in the report's estimated
    order (the top two, or every neighbour): ``a``, ``b``, ``difference``, ``ci_low``,
    ``ci_high``."""
    from analysis.study import AnalysisConfig, analyse
    from studyapp.results.export import responses_frame

    result = analyse(responses_frame(study), AnalysisConfig(bootstrap=bootstrap, seed=seed),
                     study_type=study.study_type)
    order = [str(s) for s in result.analysis.sources.sort_values("score", ascending=False).index]
    table = next(t for t in result.analysis.tables if t.name == "differences").frame
    rows = {(str(r.a), str(r.b)): (r.difference, r.ci_low, r.ci_high) for r in table.itertuples()}
    pairs = [(order[0], order[1])] if target == "top_two" else list(zip(order, order[1:]))
    out = []
    for a, b in pairs:
        if (a, b) in rows:
            d, low, high = rows[(a, b)]
        else:  # the table has b - a
            d, low, high = -rows[(b, a)][0], -rows[(b, a)][2], -rows[(b, a)][1]
        out.append({"a": a, "b": b, "difference": float(d), "ci_low": float(low),
                    "ci_high": float(high)})
    return out


def measure(study, run: dict, target: str, clip_sd: float, seed: int, bootstrap: int) -> dict:
    """Return what one study gave: judgements at the stop and at the end, the report's
    intervals of the target and their coverage of both truths."""
    from studyapp.participation.adaptive import answered_main

    study.refresh_from_db()
    population = truth(STRENGTHS, clip_sd)
    own = these_clips_truth(clip_qualities(study, clip_sd, seed))
    index = {name: i for i, name in enumerate(SOURCES)}
    intervals = report_intervals(study, target, bootstrap, seed)
    for row in intervals:
        a, b = index[row["a"]], index[row["b"]]
        row["truth_population"] = float(population[a] - population[b])
        row["truth_these_clips"] = float(own[a] - own[b])
        row["covers_population"] = row["ci_low"] <= row["truth_population"] <= row["ci_high"]
        row["covers_these_clips"] = row["ci_low"] <= row["truth_these_clips"] <= row["ci_high"]
    stopped = study.stopped or {}
    return {
        "study": study.slug, "design": study.design, "seed": seed,
        "reached": bool(stopped), "ended_by": run["ended_by"],
        "judgements_at_stop": stopped.get("judgements"),
        "rule_width_at_stop": stopped.get("width"),
        "judgements_in_the_end": answered_main(study),
        "participants": run["participants"], "bot_errors": len(run["errors"]),
        "bot_error_samples": run["errors"][:3],
        "seconds": run["seconds"],
        "report_width": max(r["ci_high"] - r["ci_low"] for r in intervals),
        "covered_population": all(r["covers_population"] for r in intervals),
        "covered_these_clips": all(r["covers_these_clips"] for r in intervals),
        "intervals": intervals,
    }


def run_pair(url: str, clips: list, seed: int, *, target="top_two", width=1.2, trials=10,
             every=25, batch=None, clip_sd=0.3, concurrency=6, budget=3000, time_limit=900.0,
             bootstrap=1000, designs=DESIGNS) -> list[dict]:
    """Create one study per design of the same ``clips`` and send bots to all of them at
    once (one thread per study) on the running server ``url``; return each study's
    :func:`measure`. The database must be the server's, and Django set up in this process."""
    from studyapp.participation.adaptive import answered_main

    studies = [make_study(f"bench-{design}-{seed}-{os.getpid()}", design, clips, target,
                          width, trials, every, batch) for design in designs]
    runs = [None] * len(studies)

    def arm(k):
        runs[k] = take_part(studies[k], url, seed, clip_sd, concurrency, budget, time_limit)

    threads = [threading.Thread(target=arm, args=(k,), daemon=True) for k in range(len(studies))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for study, run in zip(studies, runs):
        if not answered_main(study):
            raise RuntimeError(f"{study.slug}: no answers; the bots: {run['errors'][:3]}")
    return [measure(study, run, target, clip_sd, seed, bootstrap)
            for study, run in zip(studies, runs)]


def run_replicates(url: str, clips: list, seeds: list[int], parallel: int = 1, **settings):
    """Run :func:`run_pair` for each of ``seeds``, ``parallel`` replicates at once (each in
    a thread of its own, its database connection closed at its end; a new one starts when
    one ends); yield each replicate's list as it ends."""
    from django.db import connections

    def one(seed):
        try:
            return run_pair(url, clips, seed, **settings)
        finally:
            connections.close_all()  # this thread's

    pool = ThreadPoolExecutor(max_workers=max(1, parallel))
    try:
        for future in as_completed([pool.submit(one, seed) for seed in seeds]):
            yield future.result()
    finally:
        # A failed replicate (or a stopped run) cancels the replicates not started yet
        # rather than running them all before its error is seen.
        pool.shutdown(wait=True, cancel_futures=True)


def summary(results: list[dict], designs=DESIGNS) -> list[dict]:
    """Return per design: studies, reached, median and mean judgements (at the stop and in
    the end), mean report width, coverage of both truths (studies whose intervals all
    covered, and intervals)."""
    out = []
    for design in designs:
        mine = [r for r in results if r["design"] == design]
        if not mine:
            continue
        at_stop = [r["judgements_at_stop"] for r in mine if r["reached"]]
        end = [r["judgements_in_the_end"] for r in mine]
        out.append({
            "design": design, "studies": len(mine), "reached": sum(r["reached"] for r in mine),
            "median_at_stop": float(np.median(at_stop)) if at_stop else None,
            "mean_at_stop": float(np.mean(at_stop)) if at_stop else None,
            "mean_in_the_end": float(np.mean(end)),
            "each_at_stop": [r["judgements_at_stop"] for r in mine],
            "mean_report_width": float(np.mean([r["report_width"] for r in mine])),
            "covered_population": sum(r["covered_population"] for r in mine),
            "covered_these_clips": sum(r["covered_these_clips"] for r in mine),
            "intervals": sum(len(r["intervals"]) for r in mine),
            "intervals_covering_population": sum(i["covers_population"] for r in mine
                                                 for i in r["intervals"]),
            "intervals_covering_these_clips": sum(i["covers_these_clips"] for r in mine
                                                  for i in r["intervals"]),
        })
    return out


def table(rows: list[dict], target: str, width: float) -> str:
    """The summary as Markdown: "vs balanced" compares the means at the stop, "median vs
    balanced" the medians; "covered" counts studies whose intervals all covered the truth,
    "intervals covered" the share of intervals (their number in brackets)."""
    base = next((r["mean_at_stop"] for r in rows if r["design"] == "balanced"), None)
    base_median = next((r["median_at_stop"] for r in rows if r["design"] == "balanced"), None)
    lines = ["| target (width) | design | reached | judgements at stop (each) | median | mean | "
             "vs balanced | median vs balanced | mean in the end | report width (mean) | "
             "covered: population | covered: these clips | intervals covered: population | "
             "intervals covered: these clips |", "|" + "---|" * 14]
    for r in rows:
        versus = (f"{100 * (r['mean_at_stop'] / base - 1):+.0f}%"
                  if base and r["mean_at_stop"] is not None else "")
        versus_median = (f"{100 * (r['median_at_stop'] / base_median - 1):+.0f}%"
                         if base_median and r["median_at_stop"] is not None else "")
        n = r.get("intervals") or 0
        share = (lambda k: f"{r[k] / n:.3f} ({n})" if n else "-")
        each = ", ".join(str(n) if n is not None else "-" for n in r["each_at_stop"])
        fmt = (lambda v: f"{v:.0f}" if v is not None else "-")
        lines.append(
            f"| {target} ({width}) | {r['design']} | {r['reached']}/{r['studies']} | {each} | "
            f"{fmt(r['median_at_stop'])} | {fmt(r['mean_at_stop'])} | {versus} | "
            f"{versus_median} | {r['mean_in_the_end']:.0f} | {r['mean_report_width']:.2f} | "
            f"{r['covered_population']}/{r['studies']} | "
            f"{r['covered_these_clips']}/{r['studies']} | "
            f"{share('intervals_covering_population')} | "
            f"{share('intervals_covering_these_clips')} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--studies", type=int, default=3,
                        help="Replicates (one study per design each).")
    parser.add_argument("--target", choices=("top_two", "order"), default="top_two")
    parser.add_argument("--width", type=float, default=1.2,
                        help="stop_when: {interval_width: W} (logit scale).")
    parser.add_argument("--clips", type=int, default=6, help="Clips per source.")
    parser.add_argument("--clip-sd", type=float, default=0.3)
    parser.add_argument("--trials", type=int, default=10, help="Pairs per participant.")
    parser.add_argument("--every", type=int, default=25, help="adaptive.every")
    parser.add_argument("--batch", type=int, default=None,
                        help="adaptive.batch: comparisons planned as one batch (0: none; left "
                             "out: the app's default, a batch of --every for --target order).")
    parser.add_argument("--concurrency", type=int, default=6, help="Bots at once per study.")
    parser.add_argument("--parallel", type=int, default=1,
                        help="Replicates at once (each its two studies at the same time).")
    parser.add_argument("--workers", type=int, default=3, help="gunicorn workers.")
    parser.add_argument("--budget", type=int, default=3000,
                        help="Stop sending bots to a study at this many answered main trials.")
    parser.add_argument("--time-limit", type=float, default=900, help="Seconds per study at most.")
    parser.add_argument("--bootstrap", type=int, default=1000)
    parser.add_argument("--first-seed", type=int, default=1000)
    parser.add_argument("--database", choices=("postgres", "sqlite"), default="postgres")
    parser.add_argument("--db-name", default=f"bench_adaptive_srv_{os.getpid()}",
                        help="The PostgreSQL database to create (and drop at the end).")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--summarise", type=Path, metavar="RUN.json",
                        help="Print the table of an earlier run's --json file (no server).")
    args = parser.parse_args(argv)
    if args.summarise:
        run = json.loads(args.summarise.read_text())
        results = sorted(run["studies"], key=lambda r: (r["seed"], DESIGNS.index(r["design"])))
        print(table(summary(results), run["args"]["target"], float(run["args"]["width"])))
        return 0

    from benchmarks.server import Server, create_database, drop_database, server_env

    var = Path(tempfile.mkdtemp(prefix="bench-adaptive-server-"))
    name = args.db_name
    if args.database == "postgres":
        url = create_database(name)
    else:
        url = f"sqlite:///{var / 'db.sqlite3'}"
    env = server_env(url, var, STUDY_ENTRY_RATE_LIMIT="1000000/min",
                     STUDY_ENTRY_RATE_LIMIT_PER_STUDY="1000000/h", STUDY_CELERY_BROKER="")
    os.environ.update(DATABASE_URL=url, STUDY_DATABASE_URL=url, STUDY_VAR_DIR=str(var),
                      DJANGO_SETTINGS_MODULE="studyapp.settings", DJANGO_DEBUG="1",
                      STUDY_CELERY_BROKER="")
    begun = time.perf_counter()
    server = None
    try:
        import django
        from django.core.management import call_command

        django.setup()
        call_command("migrate", verbosity=0)
        clips = write_clips(var / "clips", args.clips)
        server = Server(env, workers=args.workers, settings="benchmarks.loadtest_settings",
                        log=var / "server.log")
        server.collectstatic()
        server.start(timeout=180)
        results = []
        seeds = [args.first_seed + r for r in range(args.studies)]
        bots_begun = time.perf_counter()
        for pair in run_replicates(server.url, clips, seeds, args.parallel, target=args.target,
                                   width=args.width, trials=args.trials, every=args.every,
                                   batch=args.batch, clip_sd=args.clip_sd,
                                   concurrency=args.concurrency, budget=args.budget,
                                   time_limit=args.time_limit, bootstrap=args.bootstrap):
            for one in pair:
                print(f"seed {one['seed']} {one['design']}: stop at {one['judgements_at_stop']} "
                      f"({one['ended_by']}), {one['judgements_in_the_end']} in the end, "
                      f"{one['participants']} bots ({one['bot_errors']} turned away or failed), "
                      f"report width {one['report_width']:.2f}, covered population "
                      f"{one['covered_population']} these clips {one['covered_these_clips']}, "
                      f"{one['seconds']:.0f} s", flush=True)
            results.extend(pair)
        elapsed = time.perf_counter() - begun
        answers = sum(r["judgements_in_the_end"] for r in results)
        results.sort(key=lambda r: (r["seed"], DESIGNS.index(r["design"])))
        rows = summary(results)
        print(f"\n{args.studies} studies per design, {elapsed:.0f} s in all; "
              f"{answers} answers in {time.perf_counter() - bots_begun:.0f} s of replicates "
              f"({answers / (time.perf_counter() - bots_begun):.1f} a second)")
        print(table(rows, args.target, args.width))
        if args.json:
            args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                             "elapsed_s": elapsed, "summary": rows,
                                             "studies": results}, indent=1, default=str))
        return 0
    finally:
        if server is not None:
            server.stop()
        from django.db import connections

        connections.close_all()
        if args.database == "postgres":
            drop_database(name)
        shutil.rmtree(var, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
