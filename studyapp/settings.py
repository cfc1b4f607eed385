"""Settings of the study tool.

Everything a deployment changes comes from the environment:

- ``STUDY_DATABASE_URL`` / ``DATABASE_URL``: ``postgres://user:pass@host:port/name`` or
  ``sqlite:///relative/path`` or ``sqlite:////absolute/path``; default: SQLite at
  ``var/db.sqlite3``;
- ``STUDY_PREPARED_STATEMENTS=0``: PostgreSQL behind a pooler that does not keep prepared
  statements (PgBouncer in transaction mode before 1.21, or without
  ``max_prepared_statements``): the answer path's statements are then not prepared
  (``survey/models/rows.py``);
- ``STUDY_VAR_DIR``: where the database, media and demo artefacts live (default ``var/``);
- ``STUDY_CACHE_URL``: ``redis://host:6379/1`` shares the cache (rate limits) between
  workers; ``STUDY_CELERY_BROKER``: background jobs through Celery;
  ``STUDY_S3_BUCKET`` and friends: media in S3-compatible storage (end of this file);
- ``DJANGO_SECRET_KEY``, ``DJANGO_DEBUG``, ``DJANGO_ALLOWED_HOSTS``;
- with ``DJANGO_DEBUG=0`` (production, ``make serve``): ``DJANGO_SECRET_KEY`` is required,
  cookies are secure and HTTPS is enforced; ``STUDY_BEHIND_PROXY=1`` trusts the proxy's
  ``X-Forwarded-Proto`` header, ``STUDY_SSL_REDIRECT=0`` leaves redirects to the proxy.
"""

import os
from pathlib import Path
from urllib.parse import unquote, urlparse

BASE_DIR = Path(__file__).resolve().parent.parent
VAR_DIR = Path(os.environ.get("STUDY_VAR_DIR", BASE_DIR / "var"))

DEBUG = os.environ.get("DJANGO_DEBUG", "1") == "1"
SECRET_KEY = os.environ.get("DJANGO_SECRET_KEY", "")
if not SECRET_KEY:
    if not DEBUG:
        raise RuntimeError(
            "DJANGO_SECRET_KEY must be set when DJANGO_DEBUG=0 (production): a long random "
            "string, e.g. from python3 -c 'import secrets; print(secrets.token_urlsafe(50))'"
        )
    SECRET_KEY = "dev-only-insecure-key-set-DJANGO_SECRET_KEY"
ALLOWED_HOSTS = os.environ.get("DJANGO_ALLOWED_HOSTS", "127.0.0.1,localhost,testserver").split(",")

SILENCED_SYSTEM_CHECKS = []
if not DEBUG:
    SESSION_COOKIE_SECURE = True
    CSRF_COOKIE_SECURE = True
    SECURE_SSL_REDIRECT = os.environ.get("STUDY_SSL_REDIRECT", "1") == "1"
    if not SECURE_SSL_REDIRECT:
        # Redirecting to HTTPS is left to the proxy in front (docs/PRODUCTION.md): the
        # deploy check's warning about it would stop `make serve`.
        SILENCED_SYSTEM_CHECKS.append("security.W008")
    SECURE_HSTS_SECONDS = int(os.environ.get("STUDY_HSTS_SECONDS", "31536000"))
    SECURE_HSTS_INCLUDE_SUBDOMAINS = True
    SECURE_HSTS_PRELOAD = True
    if os.environ.get("STUDY_BEHIND_PROXY") == "1":
        SECURE_PROXY_SSL_HEADER = ("HTTP_X_FORWARDED_PROTO", "https")
SESSION_COOKIE_HTTPONLY = True
X_FRAME_OPTIONS = "DENY"

INSTALLED_APPS = [
    "django.contrib.admin",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "studyapp.survey",
    # Rooms of one concern beside the study itself (each brings its own commands):
    "studyapp.participation",
    "studyapp.stimuli",
    "studyapp.crowd",
    "studyapp.results",
    "studyapp.offline",
]

MIDDLEWARE = [
    "django.middleware.security.SecurityMiddleware",
    "studyapp.survey.middleware.DatabaseUnavailableMiddleware",
    "whitenoise.middleware.WhiteNoiseMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
    "studyapp.participation.ratelimit.EntryRateLimitMiddleware",
]

# New participants per IP address (entry link and consent); generous for shared NATs.
STUDY_ENTRY_RATE_LIMIT = os.environ.get("STUDY_ENTRY_RATE_LIMIT", "120/min")
# New participants (consents) per study and IP address: one address cannot fill a study.
STUDY_ENTRY_RATE_LIMIT_PER_STUDY = os.environ.get("STUDY_ENTRY_RATE_LIMIT_PER_STUDY", "60/h")
# Failed admin logins per IP address (counted in the database); past it the login page
# answers 429 for the window.
STUDY_LOGIN_RATE_LIMIT = os.environ.get("STUDY_LOGIN_RATE_LIMIT", "10/h")
# An answer is taken only this many times the clips' length after its page was served
# (and once every clip was fetched whole). 1: as long as the clips play. Tests of other
# things lower it; a study should not.
STUDY_WATCH_TIME_FACTOR = 1.0
# Background jobs (stimulus builds, long analyses) go to Celery when a broker is set,
# e.g. redis://127.0.0.1:6379/0; otherwise they run in a thread of the web process.
STUDY_CELERY_BROKER = os.environ.get("STUDY_CELERY_BROKER", "")


# Seconds a cache call may wait for Redis: a hung (not stopped) server must not hold up
# every request; the rate limits fail open when the cache does not answer.
CACHE_TIMEOUT_S = float(os.environ.get("STUDY_CACHE_TIMEOUT", "0.25"))


def cache_from_url(url: str) -> dict:
    """Return Django's CACHES: per-process memory, or Redis for ``redis://...``."""
    if not url:
        return {"default": {"BACKEND": "django.core.cache.backends.locmem.LocMemCache"}}
    if urlparse(url).scheme not in ("redis", "rediss", "unix"):
        raise ValueError(f"STUDY_CACHE_URL {url!r}: use redis://host:6379/1 (or rediss://, unix://)")
    return {"default": {
        "BACKEND": "django.core.cache.backends.redis.RedisCache", "LOCATION": url,
        "OPTIONS": {"socket_connect_timeout": CACHE_TIMEOUT_S, "socket_timeout": CACHE_TIMEOUT_S},
    }}


# The cache holds the participant-creation rate limit: set STUDY_CACHE_URL (e.g.
# redis://127.0.0.1:6379/1) so that every gunicorn worker shares it.
CACHES = cache_from_url(os.environ.get("STUDY_CACHE_URL", ""))

# Where the clip view first records that a clip was sent to its last byte (see
# studyapp/participation/fetch_log.py): Redis (batched into the database on the answer and every
# STUDY_FETCH_FLUSH_S seconds), or without it a spool folder on this machine followed
# by a direct database write (on SQLite one that does not queue for the lock).
STUDY_FETCH_LOG_URL = os.environ.get("STUDY_FETCH_LOG_URL", os.environ.get("STUDY_CACHE_URL", ""))
STUDY_FETCH_SPOOL = Path(os.environ.get("STUDY_FETCH_SPOOL", VAR_DIR / "fetches"))
STUDY_FETCH_FLUSH_S = float(os.environ.get("STUDY_FETCH_FLUSH_S", "30"))
# On SQLite, how long the clip view waits for the write lock before leaving a fetch to
# its witness (the answer, or the flushing thread, writes it then).
STUDY_FETCH_WRITE_WAIT_S = float(os.environ.get("STUDY_FETCH_WRITE_WAIT_S", "0.05"))

# Behind nginx (``make serve`` with it set, docs/PRODUCTION.md): the internal location
# (e.g. ``/protected-media/``) that the clip view hands each delivery's file to with
# ``X-Accel-Redirect``; nginx sends the bytes and its access log of that location is
# read into the fetch witnesses (``manage.py follow_fetches``). Empty: the view streams.
STUDY_ACCEL_REDIRECT = os.environ.get("STUDY_ACCEL_REDIRECT", "").strip()
if STUDY_ACCEL_REDIRECT:
    STUDY_ACCEL_REDIRECT = "/" + STUDY_ACCEL_REDIRECT.strip("/") + "/"
# Behind nginx with local media: the request sending a trial page writes its clips'
# delivery files first and nginx sends them without asking the app (nginx_config's
# clip location). "0": every clip goes through the clip view (nginx_config --no-ahead).
STUDY_DELIVER_AHEAD = os.environ.get("STUDY_DELIVER_AHEAD", "1") != "0"


def check_nodes(nodes: int, cache_url: str, fetch_log_url: str) -> None:
    """Several app nodes share nothing but the database, Redis and the media store: a
    per-process cache would let each node count its own rate limits, and a spool of
    fetch witnesses on one machine is not read by an answer taken on another."""
    if nodes > 1 and not (cache_url and fetch_log_url):
        raise RuntimeError(
            f"STUDY_NODES={nodes}: several app nodes need Redis for the rate limits and the "
            "clip-fetch witnesses (set STUDY_CACHE_URL=redis://host:6379/1 on every node; "
            "docs/PRODUCTION.md, \"Many nodes\")")


# How many app nodes serve this site (behind one load balancer): above 1, Redis is required.
STUDY_NODES = int(os.environ.get("STUDY_NODES", "1") or 1)
check_nodes(STUDY_NODES, os.environ.get("STUDY_CACHE_URL", ""), STUDY_FETCH_LOG_URL)

ROOT_URLCONF = "studyapp.urls"

TEMPLATES = [
    {
        "BACKEND": "django.template.backends.django.DjangoTemplates",
        # Each study type's trial template lives beside its module (study_types/<key>.html).
        "DIRS": [BASE_DIR / "studyapp" / "survey" / "study_types"],
        "APP_DIRS": True,
        "OPTIONS": {
            "context_processors": [
                "django.template.context_processors.request",
                "django.contrib.auth.context_processors.auth",
                "django.contrib.messages.context_processors.messages",
            ],
        },
    },
]

WSGI_APPLICATION = "studyapp.wsgi.application"


# SQLite (the embedded default): IMMEDIATE, a transaction takes the write lock when it
# begins, so concurrent participants queue for it instead of failing at a read-then-write
# upgrade; WAL, readers never wait for the writer and a commit writes the log once instead
# of a rollback journal and the database, so the lock is held for less time (the file
# gains -wal and -shm companions; copy all three, or run `sqlite3 db.sqlite3 .backup`).
SQLITE_OPTIONS = {"timeout": 30, "transaction_mode": "IMMEDIATE",
                  "init_command": "PRAGMA journal_mode=WAL;"}


def database_from_url(url: str) -> dict:
    """Return a Django DATABASES entry for a ``postgres://`` or ``sqlite:///`` URL."""
    parsed = urlparse(url)
    if parsed.scheme in ("postgres", "postgresql"):
        return {
            "ENGINE": "django.db.backends.postgresql",
            "NAME": unquote(parsed.path.lstrip("/")),
            "USER": unquote(parsed.username or ""),
            "PASSWORD": unquote(parsed.password or ""),
            "HOST": parsed.hostname or "",
            "PORT": str(parsed.port or ""),
            "CONN_MAX_AGE": 60,
        }
    if parsed.scheme == "sqlite":
        return {
            "ENGINE": "django.db.backends.sqlite3",
            # sqlite:///db.sqlite3 is relative, sqlite:////srv/db.sqlite3 absolute.
            "NAME": unquote(parsed.path)[1:] or ":memory:",
            "OPTIONS": dict(SQLITE_OPTIONS),
        }
    raise ValueError(f"DATABASE_URL {url!r}: use postgres://user@host:5432/name or "
                     f"sqlite:////absolute/path")


_DATABASE_URL = os.environ.get("STUDY_DATABASE_URL") or os.environ.get("DATABASE_URL")
DATABASES = {
    "default": database_from_url(_DATABASE_URL)
    if _DATABASE_URL
    else {
        "ENGINE": "django.db.backends.sqlite3",
        "NAME": VAR_DIR / "db.sqlite3",
        "OPTIONS": dict(SQLITE_OPTIONS),
    }
}


# The answer path's statements prepared on PostgreSQL, once per connection (rows.cursor).
STUDY_PREPARED_STATEMENTS = (os.environ.get("STUDY_PREPARED_STATEMENTS", "1").strip().lower()
                             not in ("0", "false", "no", "off"))


def ensure_folders(var_dir: Path, databases: dict) -> None:
    """Create ``var_dir`` and the folder of every SQLite file before anything opens them.

    A fresh clone has no ``var/`` (git ignores it); SQLite cannot create a file in a
    missing folder ("unable to open database file"). A folder that cannot be made (a
    read-only deployment using PostgreSQL and S3, say) is left for the first use to report.
    """
    folders = [Path(var_dir), Path(var_dir) / "static"]
    for db in databases.values():
        name = str(db.get("NAME", ""))
        if db.get("ENGINE", "").endswith("sqlite3") and name and name != ":memory:":
            folders.append(Path(name).parent)
    for folder in folders:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            pass


ensure_folders(VAR_DIR, DATABASES)

DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

AUTH_PASSWORD_VALIDATORS = []

LANGUAGE_CODE = "en-us"
TIME_ZONE = "UTC"
USE_I18N = True
USE_TZ = True

STATIC_URL = "static/"
STATIC_ROOT = VAR_DIR / "static"
STORAGES = {
    "default": {"BACKEND": "django.core.files.storage.FileSystemStorage"},
    # Compressed, content-hashed copies (collectstatic); plain files while developing.
    "staticfiles": {
        "BACKEND": "django.contrib.staticfiles.storage.StaticFilesStorage"
        if DEBUG
        else "whitenoise.storage.CompressedManifestStaticFilesStorage"
    },
}

# Stimulus videos live here under content-hash names; they are served only through
# opaque per-stimulus URLs (survey.views.clip), never from a public media URL.
MEDIA_ROOT = VAR_DIR / "media"

# Upper bound on a participant's POST body, so a tampered request cannot be huge.
DATA_UPLOAD_MAX_MEMORY_SIZE = 256 * 1024


# --- Media storage ---------------------------------------------------------------------
# Stimulus files are read and written only through ``default_storage``
# (survey.stimuli, survey.media). By default that is the FileSystemStorage above, at
# MEDIA_ROOT. With ``STUDY_S3_BUCKET`` set they live in an S3-compatible bucket
# (django-storages): ``STUDY_S3_ENDPOINT_URL`` (MinIO and other non-AWS services),
# ``STUDY_S3_REGION``, ``STUDY_S3_PREFIX`` (key prefix, default ``media``); credentials
# come from boto3's usual chain (``AWS_ACCESS_KEY_ID``/``AWS_SECRET_ACCESS_KEY``, a
# profile or an instance role). The app still streams every clip itself under its
# opaque token (survey.views.clip): no bucket URL is ever handed out, so keep the bucket
# private. Static files stay with whitenoise.


def s3_storage_from_env(environ) -> dict | None:
    """Return the ``STORAGES["default"]`` entry for S3 from the environment, or None."""
    bucket = environ.get("STUDY_S3_BUCKET", "").strip()
    if not bucket:
        return None
    return {
        "BACKEND": "storages.backends.s3.S3Storage",
        "OPTIONS": {
            "bucket_name": bucket,
            "endpoint_url": environ.get("STUDY_S3_ENDPOINT_URL") or None,
            "region_name": environ.get("STUDY_S3_REGION") or None,
            "location": environ.get("STUDY_S3_PREFIX", "media").strip("/"),
            # No ACL on upload: objects are as private as the bucket (and buckets with
            # ACLs disabled refuse uploads that set one).
            "default_acl": None,
            # Names are content hashes: the same name is the same file, never a
            # renamed copy.
            "file_overwrite": True,
        },
    }


_S3_STORAGE = s3_storage_from_env(os.environ)
if _S3_STORAGE:
    STORAGES = {**STORAGES, "default": _S3_STORAGE}
