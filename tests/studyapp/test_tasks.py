"""Background jobs: in a thread, eagerly through Celery, and through a real Redis worker."""

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.studyapp.conftest import make_ranking_study

ROOT = Path(__file__).resolve().parents[2]


def clip_dicts(clips):
    return [{"action": c.action, "source": c.source, "video": str(c.video), "poster": str(c.poster),
             "duration": c.duration, "motion_hash": c.motion_hash} for c in clips]


@pytest.mark.django_db(transaction=True)
def test_thread_job_registers_stimuli_and_a_retry_duplicates_nothing(clips, media_root, settings):
    from studyapp.survey.models import Stimulus, Study
    from studyapp.survey.tasks import run_job

    settings.STUDY_CELERY_BROKER = ""
    study = Study.objects.create_study("ranking", "jobs", "Jobs", clips_per_trial=3)
    first = run_job("register_stimuli", study="jobs", clips=clip_dicts(clips[:3]))
    first.join(30)
    # A crash after half the clips: run the whole job again.
    again = run_job("register_stimuli", study="jobs", clips=clip_dicts(clips))
    again.join(30)
    assert Stimulus.objects.filter(study=study).count() == len(clips)
    assert len(list((Path(media_root) / "stimuli").glob("*.mp4"))) == len(clips)


@pytest.mark.django_db
def test_celery_task_runs_eagerly(clips, media_root):
    from studyapp.celery import run_task
    from studyapp.survey.models import Stimulus

    study = make_ranking_study(clips[:2], slug="eager")
    # apply() runs the task here as task_always_eager would, without changing the app.
    ids = run_task.apply(args=("register_stimuli", {"study": "eager", "clips": clip_dicts(clips)})).get()
    assert len(ids) == len(clips) == Stimulus.objects.filter(study=study).count()
    with pytest.raises(KeyError):
        run_task.apply(args=("no_such_job", {})).get()


def redis_up() -> bool:
    try:
        socket.create_connection(("127.0.0.1", 6379), timeout=1).close()
        return True
    except OSError:
        return False


@pytest.mark.slow
@pytest.mark.skipif(not redis_up(), reason="no Redis on 127.0.0.1:6379")
@pytest.mark.django_db(transaction=True)
def test_real_redis_broker_and_worker(clips, media_root, settings):
    from django.db import connection

    from studyapp.survey.models import Stimulus, Study
    from studyapp.survey.tasks import run_job

    db = connection.settings_dict
    url = (f"sqlite:///{db['NAME']}" if connection.vendor == "sqlite"
           else f"postgres://{db['USER'] or 'postgres'}@{db['HOST']}:{db['PORT'] or 5432}/{db['NAME']}")
    broker = f"redis://127.0.0.1:6379/{7 + os.getpid() % 8}"
    settings.STUDY_CELERY_BROKER = broker
    env = dict(os.environ, STUDY_CELERY_BROKER=broker, DATABASE_URL=url, STUDY_DATABASE_URL=url,
               STUDY_VAR_DIR=str(Path(media_root).parent), PYTHONPATH=str(ROOT))
    import studyapp.celery as celery_module

    celery_module.app.conf.broker_url = broker
    celery_module.app.conf.result_backend = broker
    celery_module.app._local.__dict__.pop("backend", None)  # forget a backend built earlier
    celery_module.app.close()  # and the producer pool of the earlier broker
    celery_module.app._pool = None
    study = Study.objects.create_study("ranking", "redis-jobs", "Jobs", clips_per_trial=3)
    worker = subprocess.Popen(
        [sys.executable, "-m", "celery", "-A", "studyapp", "worker", "--pool", "solo",
         "--loglevel", "warning", "--without-gossip", "--without-mingle"],
        cwd=ROOT, env=env, start_new_session=True,
    )
    try:
        # The worker keeps MEDIA_ROOT of its own settings: pass absolute paths, check rows.
        result = run_job("register_stimuli", study="redis-jobs", clips=clip_dicts(clips))
        ids = result.get(timeout=45)
        assert len(ids) == len(clips)
        again = run_job("register_stimuli", study="redis-jobs", clips=clip_dicts(clips)).get(timeout=30)
        assert again == ids
        assert Stimulus.objects.filter(study=study).count() == len(clips)
    finally:
        worker.terminate()
        try:
            worker.wait(15)
        except subprocess.TimeoutExpired:
            worker.kill()
