"""A build's clips rendered by 1 and by 2 Celery render workers, side by side in one run.

    .venv/bin/python benchmarks/bench_fanout.py                # 24 mesh clips, print
    .venv/bin/python benchmarks/bench_fanout.py --clips 500    # the issue's 500-clip set
    .venv/bin/python benchmarks/bench_fanout.py --write        # and update docs/BENCHMARKS.md

Needs Redis on 127.0.0.1:6379 (``--redis``). Each round starts its workers
(``celery -A studyapp worker -Q render --pool solo``, as docs/PRODUCTION.md runs them),
waits until every one answers and has drawn a warm-up clip, then times
``survey.render_fanout.fan_out`` (what ``build_stimuli --workers celery`` runs) on a
fresh renders folder: every clip queued, drawn and its record counted by the build, so
the time is the build's render phase. Rounds alternate 1 and 2 workers (``--rounds``
pairs), so both see the same load. Clips: Human3.6M S1 walking (the demo dataset
without it), mesh style, one framing, as a build draws them.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
DOCS = ROOT / "docs" / "BENCHMARKS.md"
HEADING = "## Rendering fanned out over Celery workers"
TICKS = os.sysconf("SC_CLK_TCK")


def clips(count: int, frames: int):
    from motion.datasets import DatasetError, get_dataset

    try:
        found = get_dataset("h36m").clips(subjects=["S1"], actions=["Walking"], frames=frames)
        name = "Human3.6M S1 Walking"
    except (DatasetError, FileNotFoundError, KeyError):
        found = get_dataset("demo").clips(actions=["walk"], frames=frames)
        name = "demo walk"
    found = list(found)
    # More clips than takes: the same takes shifted a little, so every clip is its own.
    out = []
    for n in range(count):
        take = found[n % len(found)]
        out.append(take.with_joints(take.joints + 0.001 * (n // len(found)), source=f"c{n}"))
    return out, name


def cpu_seconds(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except FileNotFoundError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / TICKS  # utime, stime (threads included)


def start_workers(n: int, env: dict, log_dir: Path) -> list[subprocess.Popen]:
    return [subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool", "solo", "-Q",
         "render", "--hostname", f"bench{k}@%h", "--loglevel", "warning", "--without-gossip",
         "--without-mingle", "--without-heartbeat"],
        cwd=ROOT, env=env, start_new_session=True,
        stdout=open(log_dir / f"worker{k}.log", "w"), stderr=subprocess.STDOUT)
        for k in range(n)]


def stop(workers) -> None:
    for worker in workers:
        if worker.poll() is None:
            os.killpg(worker.pid, signal.SIGTERM)
    for worker in workers:
        try:
            worker.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(worker.pid, signal.SIGKILL)
            worker.wait(5)


def key_of(motion, settings) -> str:
    from studyapp.stimuli.build import digest

    return digest({"motion": motion.content_hash(), **settings})


def one_round(n_workers, motions, framing, args, env, scratch, app) -> dict:
    from studyapp.stimuli.render_fanout import fan_out

    settings = {"style": "mesh", "size": args.size}
    workers = start_workers(n_workers, env, scratch)
    try:
        deadline = time.monotonic() + 120
        while len(app.control.ping(timeout=1.0) or []) < n_workers:
            if time.monotonic() > deadline:
                raise SystemExit(f"{n_workers} workers did not answer in 120 s; see "
                                 f"{scratch}/worker*.log")
        warm = scratch / f"warm-{n_workers}"
        fan_out([(key_of(m, settings) + "w", m) for m in motions[:2 * n_workers]], warm,
                "mesh", args.size, framing)
        folder = scratch / f"renders-{n_workers}"
        before = sum(cpu_seconds(w.pid) for w in workers)
        load = os.getloadavg()[0]
        start = time.perf_counter()
        records, failures = fan_out([(key_of(m, settings), m) for m in motions], folder,
                                    "mesh", args.size, framing)
        wall = time.perf_counter() - start
        cpu = sum(cpu_seconds(w.pid) for w in workers) - before
        if failures:
            raise SystemExit(f"clips failed: {failures}")
        by = {}
        for record in records.values():
            by[record["by"]] = by.get(record["by"], 0) + 1
        return {"workers": n_workers, "wall": wall, "cpu": cpu, "load": load,
                "share": sorted(by.values(), reverse=True), "clips": len(records)}
    finally:
        stop(workers)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clips", type=int, default=24, help="clips per round (the issue's "
                        "figure: 500)")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--size", type=int, default=240)
    parser.add_argument("--rounds", type=int, default=1, help="pairs of rounds (1 then 2 workers)")
    parser.add_argument("--redis", default="redis://127.0.0.1:6379/14")
    parser.add_argument("--write", action="store_true", help="update docs/BENCHMARKS.md")
    args = parser.parse_args()

    scratch = Path(tempfile.mkdtemp(prefix="bench-fanout-"))
    env = dict(os.environ, STUDY_CELERY_BROKER=args.redis, STUDY_VAR_DIR=str(scratch / "var"),
               PYTHONPATH=str(ROOT))
    os.environ.update(STUDY_CELERY_BROKER=args.redis, STUDY_VAR_DIR=str(scratch / "var"),
                      DJANGO_SETTINGS_MODULE="studyapp.settings")
    import django
    import redis

    django.setup()
    from motion import ops
    from rendering import Framing, get_style
    from studyapp.celery import app

    store = redis.Redis.from_url(args.redis)
    store.flushdb()
    motions, name = clips(args.clips, args.frames)
    style = get_style("mesh")
    framing = Framing.from_motions([ops.canonical(m, style.dims) for m in motions], pad=style.pad)
    rows = []
    try:
        for _ in range(args.rounds):
            for n in (1, 2):
                row = one_round(n, motions, framing, args, env, scratch, app)
                rows.append(row)
                print(f"{n} worker(s): {row['clips']} clips in {row['wall']:.1f} s "
                      f"({row['clips'] / row['wall']:.2f} clips/s, worker CPU {row['cpu']:.0f} s, "
                      f"clips per worker {row['share']}, load {row['load']:.1f})", flush=True)
                shutil.rmtree(scratch / f"renders-{n}", ignore_errors=True)
    finally:
        store.flushdb()
        shutil.rmtree(scratch, ignore_errors=True)
    section = report(rows, args, name)
    print(section)
    if args.write:
        write_docs(section)
        print(f"written to {DOCS.relative_to(ROOT)}")


def report(rows, args, name) -> str:
    one = [r for r in rows if r["workers"] == 1]
    two = [r for r in rows if r["workers"] == 2]
    mean = lambda rs, k: sum(r[k] for r in rs) / len(rs)  # noqa: E731
    ratio = mean(one, "wall") / mean(two, "wall")
    lines = [
        HEADING,
        "",
        f"`.venv/bin/python benchmarks/bench_fanout.py --clips {args.clips}` (options "
        f"`--frames {args.frames} --size {args.size} --rounds {args.rounds}`; `--clips 500` "
        f"is the issue's set): {args.clips} {name} clips of {args.frames} frames, mesh style "
        f"at {args.size}×{args.size}, one framing, rendered by `survey.render_fanout.fan_out` "
        f"(what `build_stimuli --workers celery` runs) through Redis to 1 and then 2 Celery "
        f"render workers (`--pool solo`, each started and warmed up before it is timed), "
        f"rounds alternating in one run. {os.cpu_count()} CPU cores, shared with other work "
        f"(load average when each round began in the table).",
        "",
        "| workers | wall s | clips/s | worker CPU s | clips drawn per worker | load |",
        "|---:|---:|---:|---:|---|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['workers']} | {r['wall']:.1f} | {r['clips'] / r['wall']:.2f} | "
                     f"{r['cpu']:.0f} | {' + '.join(map(str, r['share']))} | {r['load']:.1f} |")
    lines += ["", f"- **2 workers against 1: {ratio:.2f}× the clips per second** "
              f"(mean wall {mean(one, 'wall'):.1f} s against {mean(two, 'wall'):.1f} s)."]
    return "\n".join(lines) + "\n"


def write_docs(section: str) -> None:
    text = DOCS.read_text()
    pattern = re.compile(rf"^{re.escape(HEADING)}\n.*?(?=^## |\Z)", re.M | re.S)
    if pattern.search(text):
        # Keep the hand-written notes below the measured part (from "### ").
        old = pattern.search(text).group(0)
        notes = old[old.index("### "):] if "### " in old else ""
        text = pattern.sub(lambda _: section + ("\n" + notes if notes else "\n"), text)
    else:
        text = text.rstrip("\n") + "\n\n" + section
    DOCS.write_text(text)


if __name__ == "__main__":
    main()
