"""Production settings: `check --deploy` is clean, and the environment is read as documented."""

import os
import secrets
import subprocess
import sys
from pathlib import Path

import pytest

from studyapp.settings import cache_from_url, database_from_url

ROOT = Path(__file__).resolve().parents[2]


def manage(*args, **env):
    # A fresh shell: none of this suite's settings (the PostgreSQL run's DATABASE_URL too).
    environ = {k: v for k, v in os.environ.items()
               if not k.startswith(("DJANGO_", "STUDY_")) and k != "DATABASE_URL"}
    environ.update(env)
    return subprocess.run([sys.executable, "manage.py", *args], cwd=ROOT, env=environ,
                          capture_output=True, text=True, timeout=120)


def test_check_deploy_is_clean_with_production_settings(tmp_path):
    done = manage("check", "--deploy", "--fail-level", "WARNING", DJANGO_DEBUG="0",
                  DJANGO_SECRET_KEY=secrets.token_urlsafe(50),
                  DJANGO_ALLOWED_HOSTS="study.example.org", STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "no issues" in done.stdout


def test_production_without_a_secret_key_says_how_to_make_one(tmp_path):
    done = manage("check", DJANGO_DEBUG="0", STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode != 0
    assert "DJANGO_SECRET_KEY must be set" in done.stderr and "token_urlsafe" in done.stderr


def test_development_settings_are_not_deploy_clean(tmp_path):
    # The check is not vacuous: DEBUG on and the built-in key are reported.
    done = manage("check", "--deploy", "--fail-level", "WARNING", STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode != 0
    assert "DEBUG" in done.stderr + done.stdout


def test_database_urls():
    pg = database_from_url("postgres://ann:p%40ss@db.example.org:6543/studies")
    assert (pg["ENGINE"], pg["NAME"], pg["USER"], pg["PASSWORD"], pg["HOST"], pg["PORT"]) == (
        "django.db.backends.postgresql", "studies", "ann", "p@ss", "db.example.org", "6543")
    lite = database_from_url("sqlite:////tmp/x.sqlite3")
    assert lite["NAME"] == "/tmp/x.sqlite3" and lite["OPTIONS"]["transaction_mode"] == "IMMEDIATE"
    assert database_from_url("sqlite:///var/db.sqlite3")["NAME"] == "var/db.sqlite3"
    assert database_from_url("sqlite://")["NAME"] == ":memory:"
    assert "journal_mode=WAL" in lite["OPTIONS"]["init_command"]
    with pytest.raises(ValueError, match="DATABASE_URL 'mysql://x'"):
        database_from_url("mysql://x")


def test_cache_urls():
    assert cache_from_url("")["default"]["BACKEND"].endswith("LocMemCache")
    redis = cache_from_url("redis://127.0.0.1:6379/1")["default"]
    assert redis["BACKEND"] == "django.core.cache.backends.redis.RedisCache"
    assert redis["LOCATION"] == "redis://127.0.0.1:6379/1"
    assert 0 < redis["OPTIONS"]["socket_timeout"] <= 1  # a hung Redis must not stall pages
    with pytest.raises(ValueError, match="STUDY_CACHE_URL 'memcached://x'.*redis://"):
        cache_from_url("memcached://x")


def test_a_fresh_clone_without_var_migrates(tmp_path):
    # git ignores var/: the first command must make it (and the SQLite file's folder).
    var = tmp_path / "fresh" / "var"
    done = manage("migrate", "--noinput", STUDY_VAR_DIR=str(var))
    assert done.returncode == 0, done.stdout + done.stderr
    assert (var / "db.sqlite3").is_file()
    nested = tmp_path / "elsewhere" / "deeper" / "db.sqlite3"
    done = manage("migrate", "--noinput", STUDY_VAR_DIR=str(var),
                  DATABASE_URL=f"sqlite:///{nested}")
    assert done.returncode == 0, done.stdout + done.stderr
    assert nested.is_file()


def test_demo_refuses_a_taken_port_before_building(tmp_path):
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = manage("demo", "--addr", f"127.0.0.1:{port}", STUDY_VAR_DIR=str(tmp_path))
        assert done.returncode != 0
        assert f"port {port} on 127.0.0.1 is in use" in done.stderr
        assert f"make demo PORT={port + 10}" in done.stderr
        assert not (tmp_path / "demo").exists()  # nothing was built


def test_studies_links_use_the_address_served(tmp_path):
    from studyapp.survey import site

    assert site.url_of("0.0.0.0:8010") == "http://127.0.0.1:8010"
    with pytest.raises(site.AddressError, match="HOST:PORT"):
        site.split_addr("localhost:http")
    (tmp_path / "served.json").write_text('{"base_url": "http://127.0.0.1:8010"}')
    done = manage("studies", STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode != 0 and "run `python manage.py migrate`" in done.stderr
    assert "Traceback" not in done.stderr
    assert manage("migrate", "--noinput", STUDY_VAR_DIR=str(tmp_path)).returncode == 0
    make = ("from studyapp.survey.models import Study; "
            "Study.objects.create_study('ranking', 'links', 'Links', clips_per_trial=3)")
    assert manage("shell", "-c", make, STUDY_VAR_DIR=str(tmp_path)).returncode == 0
    done = manage("studies", STUDY_VAR_DIR=str(tmp_path))
    assert "http://127.0.0.1:8010/s/links/" in done.stdout, done.stderr
    done = manage("studies", STUDY_VAR_DIR=str(tmp_path), STUDY_BASE_URL="https://study.example.org/")
    assert "https://study.example.org/s/links/" in done.stdout, done.stderr


def test_several_nodes_without_redis_refuse_to_start_and_say_why(tmp_path):
    from studyapp.settings import check_nodes

    check_nodes(1, "", "")  # one node: the spool and per-process limits are enough
    check_nodes(3, "redis://h:6379/1", "redis://h:6379/1")
    done = manage("check", STUDY_NODES="2", STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode != 0
    assert "STUDY_NODES=2" in done.stderr and "STUDY_CACHE_URL=redis://" in done.stderr


def test_accel_location_is_one_path_with_slashes_around_it(tmp_path):
    done = manage("shell", "-c", "from django.conf import settings; print(settings.STUDY_ACCEL_REDIRECT)",
                  STUDY_ACCEL_REDIRECT="protected-media", STUDY_VAR_DIR=str(tmp_path))
    assert done.stdout.strip().splitlines()[-1] == "/protected-media/", done.stderr


def test_the_embedded_database_writes_ahead_to_a_log(tmp_path):
    """The default database (SQLite in the var folder) is opened in WAL mode: readers do
    not wait for the writer, and a commit holds the write lock for less time."""
    done = manage("shell", "-c", "from django.db import connection; c = connection.cursor(); "
                  "c.execute('PRAGMA journal_mode'); print(c.fetchone()[0])",
                  STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-1] == "wal"
