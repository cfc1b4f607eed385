#!/usr/bin/env bash
# Serve the study app in production: migrations, static files, gunicorn.
# Needs DJANGO_SECRET_KEY and DJANGO_ALLOWED_HOSTS; see README, "Production".
set -euo pipefail
cd "$(dirname "$0")/.."
export DJANGO_DEBUG=${DJANGO_DEBUG:-0}
: "${DJANGO_SECRET_KEY:?set DJANGO_SECRET_KEY (e.g. python3 -c 'import secrets; print(secrets.token_urlsafe(50))')}"
: "${DJANGO_ALLOWED_HOSTS:?set DJANGO_ALLOWED_HOSTS to the public host name(s), comma-separated}"
.venv/bin/python manage.py check --deploy --fail-level WARNING
.venv/bin/python manage.py migrate --noinput
.venv/bin/python manage.py collectstatic --noinput --verbosity 0
exec .venv/bin/gunicorn studyapp.wsgi \
  --bind "${STUDY_BIND:-127.0.0.1:8000}" \
  --workers "${STUDY_WORKERS:-$(( $(nproc) * 2 + 1 ))}" \
  --timeout 30 --graceful-timeout 20 \
  --access-logfile - --error-logfile -
