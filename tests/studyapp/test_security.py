"""Security and operations: the admin's results page and permissions, login throttling,
formula injection in CSV exports, a proxy that redirects to HTTPS, a hung cache."""

import os
import secrets
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pandas as pd
import pytest
from django.contrib.auth.models import Permission, User
from django.core.management import call_command
from django.test import Client, override_settings

from studyapp.settings import cache_from_url
from tests.studyapp.conftest import make_ranking_study

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.django_db


def staff(*codenames) -> Client:
    user = User.objects.create_user("helper", password="x", is_staff=True)
    user.user_permissions.set(Permission.objects.filter(codename__in=codenames))
    client = Client()
    client.force_login(user)
    return client


def test_results_need_permissions_and_the_report_may_be_framed_here(clips, media_root,
                                                                    settings, tmp_path):
    settings.VAR_DIR = tmp_path
    study = make_ranking_study(clips)
    report = tmp_path / "reports" / study.slug / "report.html"
    report.parent.mkdir(parents=True)
    report.write_text("<html>report</html>")
    page = f"/admin/survey/study/{study.pk}/results/"
    nobody = staff()
    assert nobody.get(page).status_code == 403
    assert nobody.post(page).status_code == 403
    assert nobody.get(page + "report/").status_code == 403
    viewer = Client()
    viewer.force_login(User.objects.create_user("viewer", password="x", is_staff=True))
    User.objects.get(username="viewer").user_permissions.set(
        Permission.objects.filter(codename="view_study"))
    assert viewer.get(page).status_code == 200
    framed = viewer.get(page + "report/")
    assert framed.status_code == 200 and framed["X-Frame-Options"] == "SAMEORIGIN"
    assert viewer.post(page).status_code == 403  # viewing is not starting an analysis


def test_wrong_admin_passwords_are_throttled(settings):
    settings.STUDY_LOGIN_RATE_LIMIT = "5/h"
    User.objects.create_superuser("admin", "", "right-password")
    client = Client()
    statuses = [client.post("/admin/login/", {"username": "admin", "password": f"guess{i}"})
                .status_code for i in range(8)]
    assert statuses[:5] == [200] * 5 and statuses[5:] == [429] * 3
    refused = client.post("/admin/login/", {"username": "admin", "password": "right-password"})
    assert refused.status_code == 429 and int(refused["Retry-After"]) > 0
    assert b"Too many failed logins" in refused.content
    other = Client(REMOTE_ADDR="10.1.2.3")  # another address is not held up
    assert other.post("/admin/login/", {"username": "admin", "password": "right-password"}
                      ).status_code == 302


def test_csv_cells_a_spreadsheet_would_run_are_neutralised(clips, media_root, make_bot,
                                                           tmp_path):
    study = make_ranking_study(clips, ask_demographics=True)
    bot = make_bot(study)
    bot.join(PROLIFIC_PID='=HYPERLINK("https://evil.example","x")')
    bot.finish()
    bot.client.post(bot.url("about-you"), {"comments": "@SUM(1+1)"})
    out, people = tmp_path / "r.csv", tmp_path / "p.csv"
    call_command("export_responses", study=study.slug, out=str(out), participants=str(people))
    table = pd.read_csv(out)
    assert table["PROLIFIC_PID"].str.startswith("'=HYPERLINK").all()
    assert pd.read_csv(people)["comments"].tolist() == ["'@SUM(1+1)"]
    assert (table["rank"] > 0).all()  # numbers are left alone


def manage(*args, **env):
    environ = {k: v for k, v in os.environ.items() if not k.startswith(("DJANGO_", "STUDY_"))}
    environ.update(env)
    return subprocess.run([sys.executable, "manage.py", *args], cwd=ROOT, env=environ,
                          capture_output=True, text=True, timeout=120)


def test_a_proxy_that_redirects_to_https_passes_the_deploy_check(tmp_path):
    # docs/PRODUCTION.md: behind a redirecting proxy, STUDY_SSL_REDIRECT=0; make serve
    # runs check --deploy --fail-level WARNING first and must not stop there.
    done = manage("check", "--deploy", "--fail-level", "WARNING", DJANGO_DEBUG="0",
                  DJANGO_SECRET_KEY=secrets.token_urlsafe(50), DJANGO_ALLOWED_HOSTS="study.example.org",
                  STUDY_SSL_REDIRECT="0", STUDY_BEHIND_PROXY="1", STUDY_VAR_DIR=str(tmp_path))
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.fixture
def hung_redis():
    """A TCP server that accepts connections and never answers (a hung Redis)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    held, stop = [], threading.Event()

    def accept():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                held.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield f"redis://127.0.0.1:{server.getsockname()[1]}/0"
    stop.set()
    thread.join(2)
    for conn in held:
        conn.close()
    server.close()


def test_a_hung_cache_does_not_hold_up_entry(hung_redis, clips, media_root):
    caches = cache_from_url(hung_redis)
    options = caches["default"]["OPTIONS"]
    assert options["socket_timeout"] <= 0.5 and options["socket_connect_timeout"] <= 0.5
    study = make_ranking_study(clips)
    with override_settings(CACHES=caches, STUDY_ENTRY_RATE_LIMIT="2/min"):
        # The limit fails open when the cache does not answer: everyone still gets in.
        statuses = [Client().get(f"/s/{study.slug}/").status_code for _ in range(3)]
    assert statuses == [302] * 3


def test_tokens_never_start_as_a_spreadsheet_formula(monkeypatch):
    """A token starting with "-" would be written to the CSV export as "'-..." (a formula
    neutralised) and no longer read back as itself: such draws are drawn again."""
    from studyapp.survey.models import study as models

    draws = iter(["-d8opZFlI_z2lmBZ6uhYaA", "_x8opZFlI_z2lmBZ6uhYaA", "Qd8opZFlI_z2lmBZ6uhYaA"])
    monkeypatch.setattr(models.secrets, "token_urlsafe", lambda n: next(draws))
    assert models.new_token() == "Qd8opZFlI_z2lmBZ6uhYaA"
