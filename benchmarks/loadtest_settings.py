"""Production settings plus the middleware proposed in docs/PRODUCTION.md, for the load test."""

import os

from studyapp.settings import *  # noqa: F403
from studyapp.settings import MIDDLEWARE

MIDDLEWARE = [
    *MIDDLEWARE[:1],
    "studyapp.survey.middleware.DatabaseUnavailableMiddleware",
    *MIDDLEWARE[1:],
    "studyapp.survey.ratelimit.EntryRateLimitMiddleware",
]

STUDY_ENTRY_RATE_LIMIT = os.environ.get("STUDY_ENTRY_RATE_LIMIT", "120/min")  # noqa: F405

# Tracebacks of 500s to gunicorn's log (the default sends them only to mail_admins).
LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "handlers": {"console": {"class": "logging.StreamHandler"}},
    "loggers": {"django.request": {"handlers": ["console"], "level": "ERROR"}},
}

# Proposed fix in studyapp/settings.py (database_from_url): a sqlite:/// URL gets the
# same options as the default SQLite database, or concurrent submits fail at once with
# "database is locked" (a deferred transaction cannot upgrade to a write lock).
if DATABASES["default"]["ENGINE"].endswith("sqlite3"):  # noqa: F405
    DATABASES["default"]["OPTIONS"] = {"timeout": 30, "transaction_mode": "IMMEDIATE"}  # noqa: F405
