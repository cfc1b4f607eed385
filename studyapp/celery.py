"""The Celery app, used when ``STUDY_CELERY_BROKER`` is set: ``celery -A studyapp worker``."""

import os

from celery import Celery

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.settings")

app = Celery("studyapp")
app.conf.update(
    broker_url=os.environ.get("STUDY_CELERY_BROKER", "memory://"),
    result_backend=os.environ.get("STUDY_CELERY_RESULTS", os.environ.get("STUDY_CELERY_BROKER", "")) or None,
    task_acks_late=True,  # a job whose worker dies is delivered again...
    task_reject_on_worker_lost=True,
    worker_prefetch_multiplier=1,
    task_serializer="json",
    accept_content=["json"],
)


@app.task(name="studyapp.run_job", bind=True, max_retries=3)
def run_task(self, kind: str, params: dict):
    """...so every job must be idempotent (see ``survey.tasks``)."""
    import django

    django.setup()
    from studyapp.survey.tasks import execute

    return execute(kind, params)


# Jobs with a queue of their own: a build's clips go to render workers
# (``celery -A studyapp worker -Q render``), which may run on other machines.
QUEUES = {"render_clip": os.environ.get("STUDY_RENDER_QUEUE", "render")}


def enqueue(kind: str, params: dict):
    """Queue job ``kind`` for a worker; return its ``AsyncResult``."""
    return run_task.apply_async((kind, params), queue=QUEUES.get(kind))
