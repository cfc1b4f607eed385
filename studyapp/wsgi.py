"""WSGI entry point (gunicorn studyapp.wsgi).

Every view is imported here, as a worker boots and before it takes a request: otherwise
the first request of each worker (after a launch, a restart or a worker replaced) waits
for the views' imports, the analysis libraries among them (about 0.7-2 s)."""

import os

from django.core.wsgi import get_wsgi_application
from django.urls import get_resolver

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.settings")
application = get_wsgi_application()
get_resolver().url_patterns  # noqa: B018 (imports the URLconf and every view)
