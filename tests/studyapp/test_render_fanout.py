"""A build's clips rendered by two real Celery workers (Redis), one of them killed mid-build."""

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import asdict
from pathlib import Path

import pytest
import yaml

from motion import ops
from motion.datasets import get_dataset
from generation.sampling import sample_real
from rendering import Framing, get_style, render_clip, render_set
from studyapp.stimuli.render_fanout import LEASE_PREFIX, FanOutError, fan_out
from studyapp.stimuli.build import BuildError, build_stimuli, render_workers
from studyapp.stimuli.config import parse
from tests.studyapp.test_build_stimuli import small
from tests.studyapp.test_tasks import redis_up

ROOT = Path(__file__).resolve().parents[2]


def test_one_clip_at_a_time_draws_the_bytes_of_a_set(tmp_path):
    motions = sample_real(get_dataset("demo"), ["walk", "wave"], 1, 12, 0)
    style = get_style("stick")
    framing = Framing.from_motions([ops.canonical(m, style.dims) for m in motions], pad=style.pad)
    whole = render_set(motions, tmp_path / "set", style="stick", size=32, framing=framing,
                       progress=False)
    alone = [render_clip(m, tmp_path / "one", "stick", framing, 32) for m in motions]
    assert [c.video_hash for c in alone] == [c.video_hash for c in whole.clips]
    assert sorted(p.name for p in (tmp_path / "one").iterdir()) == sorted(
        f"{c.video_hash}{suffix}" for c in alone for suffix in (".mp4", ".png"))


def test_workers_option_and_a_missing_broker_say_what_to_set(settings, monkeypatch):
    assert render_workers(100, "celery") == "celery" and render_workers(100, "3") == 3
    monkeypatch.setenv("STUDY_RENDER_WORKERS", "Celery")
    assert render_workers(1) == "celery"
    with pytest.raises(BuildError, match="--workers='many'.*whole number or 'celery'"):
        render_workers(1, "many")
    settings.STUDY_CELERY_BROKER = ""
    monkeypatch.delenv("STUDY_CELERY_BROKER", raising=False)
    with pytest.raises(FanOutError, match="STUDY_CELERY_BROKER=redis://.*-Q render"):
        fan_out([], "/nonexistent", "stick", 32, None)


@pytest.mark.skipif(not redis_up(), reason="no Redis on 127.0.0.1:6379")
def test_a_build_run_again_takes_what_the_workers_drew_and_a_redelivery_draws_nothing(
        tmp_path, settings):
    import redis

    from motion.formats import npz
    from studyapp.stimuli.render_fanout import FANOUT, lease_name, render_one

    broker = f"redis://127.0.0.1:6379/{7 + os.getpid() % 8}"
    settings.STUDY_CELERY_BROKER = broker
    [motion] = sample_real(get_dataset("demo"), ["walk"], 1, 12, 0)
    style = get_style("stick")
    framing = Framing.from_motions([ops.canonical(motion, style.dims)], pad=style.pad)
    folder = tmp_path / "renders"
    (folder / FANOUT).mkdir(parents=True)
    npz.save(folder / FANOUT / "k1.npz", [motion])
    # What a worker did for a build killed since: the clip drawn, its record written.
    record = render_one(str(folder), "k1", "stick", 32, asdict(framing))
    assert (folder / f"{record['video_hash']}.mp4").is_file()
    assert not redis.Redis.from_url(broker).exists(lease_name(folder, "k1"))  # lease dropped
    drawn = {p: p.stat().st_mtime_ns for p in folder.glob("*.mp4")}
    assert render_one(str(folder), "k1", "stick", 32, asdict(framing)) == record
    seen = []
    records, failures = fan_out([("k1", motion)], folder, "stick", 32, framing,
                                on_clip=seen.append)
    assert (records, failures, seen) == ({"k1": record}, {}, ["k1"])
    assert {p: p.stat().st_mtime_ns for p in folder.glob("*.mp4")} == drawn


def use_broker(broker):
    """Point this process's Celery app at ``broker`` (it was made with another)."""
    import studyapp.celery as celery_module

    celery_module.app.conf.broker_url = broker
    celery_module.app.conf.result_backend = broker
    celery_module.app._local.__dict__.pop("backend", None)
    celery_module.app.close()
    celery_module.app._pool = None


def start_worker(name, env):
    return subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool", "solo",
         "-Q", "render", "--hostname", f"{name}@%h", "--loglevel", "warning",
         "--without-gossip", "--without-mingle", "--without-heartbeat"],
        cwd=ROOT, env=env, start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


@pytest.mark.slow  # 20-35 s: two workers start, one is killed, a lease lapses
@pytest.mark.skipif(not redis_up(), reason="no Redis on 127.0.0.1:6379")
@pytest.mark.django_db(transaction=True)
def test_two_celery_workers_one_killed_every_clip_registered_once(tmp_path, media_root,
                                                                  settings, monkeypatch):
    import redis

    from studyapp.survey.models import BuildJob, Study
    from studyapp.survey.tasks import execute

    broker = f"redis://127.0.0.1:6379/{7 + os.getpid() % 8}"
    store = redis.Redis.from_url(broker)
    store.flushdb()
    settings.STUDY_CELERY_BROKER = broker
    use_broker(broker)
    monkeypatch.setenv("STUDY_RENDER_STALL", "20")
    env = dict(os.environ, STUDY_CELERY_BROKER=broker, STUDY_VAR_DIR=str(tmp_path / "var"),
               PYTHONPATH=str(ROOT), PYOPENGL_PLATFORM="egl", STUDY_RENDER_LEASE="2")
    workers = [start_worker(f"render{n}", env) for n in (1, 2)]
    killed = {}
    building = threading.Event()

    def kill_one_mid_clip():
        """SIGKILL the first worker seen holding a lease once a clip is in."""
        pids = {str(w.pid): w for w in workers}
        while building.is_set() and not killed:
            if steps and any(m.startswith("rendered") for m in steps):
                for lease in store.scan_iter(f"{LEASE_PREFIX}*"):
                    holder = (store.get(lease) or b"").decode().rpartition(":")[2]
                    if holder in pids:
                        os.killpg(pids[holder].pid, signal.SIGKILL)
                        killed[holder] = lease.decode()[len(LEASE_PREFIX):]
                        break
            time.sleep(0.01)

    steps, said = [], []
    raw = small(frames=40, clips_per_source=3, render={"style": "mesh", "size": 64})
    killer = threading.Thread(target=kill_one_mid_clip, daemon=True)
    try:
        building.set()
        killer.start()
        result = build_stimuli(parse(raw, tmp_path), tmp_path / "build", workers="celery",
                               progress=lambda done, total, message: steps.append(message),
                               log=said.append)
        # A build started from the admin, with STUDY_RENDER_WORKERS=celery, on the worker left.
        settings.VAR_DIR = tmp_path / "var"
        monkeypatch.setenv("STUDY_RENDER_WORKERS", "celery")
        config = tmp_path / "job.yaml"
        config.write_text(yaml.safe_dump({**raw, "slug": "by-job", "render": {"style": "mesh",
                                                                              "size": 32}}))
        job = BuildJob.objects.create(config_path=str(config))
        execute("build_stimuli", {"job": job.pk})
        job.refresh_from_db()
    finally:
        building.clear()
        killer.join(5)
        for worker in workers:
            if worker.poll() is None:
                os.killpg(worker.pid, signal.SIGTERM)
        for worker in workers:
            try:
                worker.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(worker.pid, signal.SIGKILL)
                worker.wait(5)
        store.flushdb()
    assert killed, "no worker was caught drawing a clip"
    assert any("its render worker stopped; queued again" in line for line in said), said
    study = Study.objects.get(slug=raw["slug"])
    hashes = list(study.stimuli.values_list("video_hash", flat=True))
    assert len(hashes) == len(set(hashes)) == len(result.entries) == result.rendered >= 12
    assert sum(m.startswith("rendered ") for m in steps) == result.rendered
    renders = tmp_path / "build" / "renders"
    # Beside them at most the half-written file of the killed worker's clip.
    assert {p.stem for p in renders.glob("[!.]*.mp4")} == set(hashes)
    assert len(list(renders.glob(".rendering-*"))) <= 2
    assert not list((renders / ".fanout").glob("*.json"))  # records cleaned once indexed

    assert job.status == BuildJob.Status.DONE and job.done == job.total > 12
    assert job.study.stimuli.count() == len(result.entries)
    assert not set(job.study.stimuli.values_list("video_hash", flat=True)) & set(hashes)

    # The same build locally: the same files, and a rerun draws nothing.
    monkeypatch.delenv("STUDY_RENDER_WORKERS")
    local = build_stimuli(parse({**raw, "slug": "local"}, tmp_path), tmp_path / "local")
    assert sorted(e["video_hash"] for e in local.entries) == sorted(hashes)
    again = build_stimuli(parse(raw, tmp_path), tmp_path / "build", workers="celery")
    assert again.rendered == 0 and again.unchanged
