"""Where background jobs go: the Celery broker's URL (``STUDY_CELERY_BROKER``), or none.

Below both ``survey.tasks`` (jobs) and ``survey.render_fanout`` (a build's clips sent to
render workers), which each import it.
"""

import os


def broker_url() -> str:
    """Return ``STUDY_CELERY_BROKER`` from the settings or the environment ("" for none)."""
    from django.conf import settings

    return getattr(settings, "STUDY_CELERY_BROKER", "") or os.environ.get("STUDY_CELERY_BROKER", "")
