#!/usr/bin/env bash
# Serve the study app in production: migrations, static files, gunicorn; with
# STUDY_ACCEL_REDIRECT set, Debian's nginx in front of it sends the clips' bytes.
# Needs DJANGO_SECRET_KEY and DJANGO_ALLOWED_HOSTS; see docs/PRODUCTION.md.
set -euo pipefail
cd "$(dirname "$0")/.."
export DJANGO_DEBUG=${DJANGO_DEBUG:-0}
: "${DJANGO_SECRET_KEY:?set DJANGO_SECRET_KEY (e.g. python3 -c 'import secrets; print(secrets.token_urlsafe(50))')}"
: "${DJANGO_ALLOWED_HOSTS:?set DJANGO_ALLOWED_HOSTS to the public host name(s), comma-separated}"
BIND=${STUDY_BIND:-127.0.0.1:8000}
GUNICORN=(.venv/bin/gunicorn studyapp.wsgi
  --bind "$BIND"
  --workers "${STUDY_WORKERS:-$(( $(nproc) * 2 + 1 ))}"
  --timeout 30 --graceful-timeout 20
  --access-logfile - --error-logfile -)

if [ -n "${STUDY_ACCEL_REDIRECT:-}" ]; then
  # nginx on STUDY_NGINX_LISTEN in front of gunicorn: the clip view answers with
  # X-Accel-Redirect, nginx sends the delivery's file, and follow_fetches reads nginx's
  # log of those into the fetch witnesses.
  export STUDY_BEHIND_PROXY=${STUDY_BEHIND_PROXY:-1}
  NGINX=${STUDY_NGINX:-/usr/sbin/nginx}
  [ -x "$NGINX" ] || { echo "serve: $NGINX not found (apt-get install nginx), or unset STUDY_ACCEL_REDIRECT" >&2; exit 1; }
  RUN=${STUDY_NGINX_DIR:-${STUDY_VAR_DIR:-var}/nginx}
  mkdir -p "$RUN"
  RUN=$(cd "$RUN" && pwd)
  EXTRA=()
  [ "$(id -u)" = 0 ] && EXTRA+=(--user "${STUDY_NGINX_USER:-www-data}")
  for address in ${STUDY_NGINX_REAL_IP_FROM:-}; do EXTRA+=(--real-ip-from "$address"); done
  if [ -n "${STUDY_NGINX_TLS_CERT:-}" ]; then
    EXTRA+=(--tls-cert "$STUDY_NGINX_TLS_CERT" --tls-key "${STUDY_NGINX_TLS_KEY:?set STUDY_NGINX_TLS_KEY beside STUDY_NGINX_TLS_CERT}")
  fi
fi

.venv/bin/python manage.py check --deploy --fail-level WARNING
.venv/bin/python manage.py migrate --noinput
.venv/bin/python manage.py collectstatic --noinput --verbosity 0

if [ -z "${STUDY_ACCEL_REDIRECT:-}" ]; then
  exec "${GUNICORN[@]}"
fi

.venv/bin/python manage.py nginx_config --listen "${STUDY_NGINX_LISTEN:-127.0.0.1:8080}" \
  --upstream "$BIND" --run-dir "$RUN" --fetch-log "$RUN/fetches.log" \
  --proto "${STUDY_NGINX_PROTO:-\$scheme}" "${EXTRA[@]}" > "$RUN/nginx.conf"
"$NGINX" -t -q -p "$RUN" -c "$RUN/nginx.conf" -e "$RUN/error.log"
pids=()
stop() { kill "${pids[@]}" 2>/dev/null || true; wait; }
trap stop EXIT INT TERM
"$NGINX" -p "$RUN" -c "$RUN/nginx.conf" -e "$RUN/error.log" -g "daemon off;" & pids+=($!)
.venv/bin/python manage.py follow_fetches --log "$RUN/fetches.log" & pids+=($!)
"${GUNICORN[@]}" & pids+=($!)
echo "serve: nginx on ${STUDY_NGINX_LISTEN:-127.0.0.1:8080} in front of gunicorn on $BIND" >&2
wait -n
