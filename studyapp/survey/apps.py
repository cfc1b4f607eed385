from django.apps import AppConfig


class SurveyConfig(AppConfig):
    name = "studyapp.survey"
    label = "survey"
    verbose_name = "Perceptual studies"

    def ready(self):
        from django.contrib.auth.signals import user_login_failed

        from studyapp.participation.ratelimit import count_failed_login

        user_login_failed.connect(count_failed_login, dispatch_uid="survey-login-limit")
        from django.db.models.signals import pre_delete

        from studyapp.survey.models import Participant
        from studyapp.survey.models.participation import forget_balance

        pre_delete.connect(forget_balance, sender=Participant, dispatch_uid="survey-balance")
        from studyapp.participation import adaptive
        from studyapp.survey import tasks
        from studyapp.stimuli import render_fanout

        tasks.queue = _celery_queue
        render_fanout.queue = _celery_queue
        adaptive.run_job = tasks.run_job


def _celery_queue(kind: str, params: dict):
    """Queue a job with Celery (imported only when a broker is set and a job starts)."""
    from studyapp.celery import enqueue

    return enqueue(kind, params)
