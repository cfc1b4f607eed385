"""Background jobs: stimulus builds and long analyses, outside any request.

``run_job(kind, **params)`` runs the job registered as ``kind``. With
``STUDY_CELERY_BROKER`` set (``redis://127.0.0.1:6379/0``) it is queued for a Celery
worker (``celery -A studyapp worker``); otherwise it runs in a thread of this process.
Jobs must be safe to run again after a crash: ``register_stimuli`` is, because
``register_clips`` finds a video already in the study by its hash.
"""

import logging
import threading

from motion.registry import Registry
from studyapp.survey.broker import broker_url

log = logging.getLogger(__name__)
# How a job reaches a worker when a broker is set: ``queue(kind, params)`` returns its
# ``AsyncResult``. The app's ``ready`` sets it to Celery's (``studyapp.celery.enqueue``);
# this module never imports Celery, which imports this module to run the jobs.
queue = None

JOBS = Registry("job")


def register_job(kind: str):
    """Register a function as the job ``kind`` (keyword parameters, JSON-serialisable)."""

    return JOBS.register(kind)


def execute(kind: str, params: dict):
    """Run job ``kind`` here and now; return its result."""
    job = JOBS.get(kind)
    log.info("job %s %s", kind, params)
    return job(**params)


def run_job(kind: str, **params):
    """Start job ``kind``; return a Celery ``AsyncResult`` or the started thread."""
    JOBS.get(kind)  # an unknown kind fails here, not in the worker
    if broker_url():
        if queue is None:
            raise RuntimeError("STUDY_CELERY_BROKER is set but no queue is: run inside the "
                               "Django app (its ready() sets tasks.queue)")
        return queue(kind, params)
    thread = threading.Thread(target=_in_thread, args=(kind, params), name=f"job-{kind}", daemon=True)
    thread.start()
    return thread


def _in_thread(kind, params):
    from django.db import connection

    try:
        execute(kind, params)
    except Exception:
        log.exception("job %s failed", kind)
    finally:
        connection.close()


@register_job("register_stimuli")
def register_stimuli(study: str, clips: list[dict]) -> list[int]:
    """Register rendered clips with study ``study`` (slug); each clip is the fields of a
    :class:`~studyapp.stimuli.clips.Clip` (JSON: paths as text)."""
    from studyapp.survey.models import Study
    from studyapp.stimuli.clips import Clip, register_clips

    made = [Clip(**clip) for clip in clips]
    return [s.pk for s in register_clips(Study.objects.get(slug=study), made)]


@register_job("render_clip")
def render_clip(folder: str, key: str, style: str, size, framing: dict) -> dict:
    """Render one clip of a fanned-out build (queue ``render``, see ``survey.render_fanout``)."""
    from studyapp.stimuli.render_fanout import render_one

    return render_one(folder, key, style, size, framing)


@register_job("call_command")
def call_command(name: str, args: list | None = None, options: dict | None = None) -> str:
    """Run a management command (``render``, ``analyze``, ...) and return its output."""
    from io import StringIO

    from django.core.management import call_command as call

    out = StringIO()
    call(name, *(args or []), stdout=out, **(options or {}))
    return out.getvalue()


@register_job("build_stimuli")
def build_stimuli_job(job: int) -> int | None:
    """Run the stimulus build of ``BuildJob`` ``job``, recording progress; return the study id.

    Running it again after a crash is safe: the build reuses what it finished and
    ``register_clips`` never registers a video twice.
    """
    from django.utils import timezone

    from studyapp.stimuli.build_jobs import run_build
    from studyapp.survey.models import BuildJob

    jobs = BuildJob.objects.filter(pk=job)
    jobs.update(status=BuildJob.Status.RUNNING, started_at=timezone.now(), finished_at=None,
                error="", done=0, total=0, message="starting")
    record = jobs.get()

    def progress(done, total, message=""):
        jobs.update(done=done, total=total, message=str(message)[:300])

    try:
        result = run_build(record.config_path, progress, record.overrides)
    except Exception as exc:
        jobs.update(status=BuildJob.Status.FAILED, error=str(exc), finished_at=timezone.now())
        raise
    jobs.update(status=BuildJob.Status.DONE, finished_at=timezone.now(), study=result.study,
                message=f"built: {len(result.entries)} clips, {result.rendered} rendered now")
    return result.study.pk if result.study else None
