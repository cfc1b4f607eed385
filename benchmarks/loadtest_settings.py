"""The production settings, with tracebacks of 500s in gunicorn's log, for load and fault tests."""

from studyapp.settings import *  # noqa: F403

# The default sends them only to mail_admins.
LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "handlers": {"console": {"class": "logging.StreamHandler"}},
    "loggers": {"django.request": {"handlers": ["console"], "level": "ERROR"}},
}
