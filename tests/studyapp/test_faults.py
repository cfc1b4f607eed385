"""Faults: a killed server, double submits, an unreachable database.

The server tests start real gunicorn (production settings) on the test database, so
they run on SQLite and on PostgreSQL (``DATABASE_URL=postgres://...``) alike.
"""

import asyncio
import os
import threading
import time

import pytest
import redis
from django.db import OperationalError, connection

from benchmarks.loadtest import AsyncParticipant, Participant
from benchmarks.server import Server, server_env
from tests.studyapp.conftest import make_ranking_study
from tests.studyapp.test_tasks import redis_up

pytestmark = [pytest.mark.slow, pytest.mark.django_db(transaction=True)]


def database_url() -> str:
    db = connection.settings_dict
    if connection.vendor == "sqlite":
        return f"sqlite:///{db['NAME']}"
    user = db["USER"] or "postgres"
    return f"postgres://{user}@{db['HOST'] or '127.0.0.1'}:{db['PORT'] or 5432}/{db['NAME']}"


@pytest.fixture
def server(tmp_path, media_root, settings):
    settings.MEDIA_ROOT = tmp_path / "var" / "media"  # where the server reads clips from
    env = server_env(database_url(), tmp_path / "var")
    server = Server(env, workers=2, settings="benchmarks.loadtest_settings",
                    log=tmp_path / "gunicorn.log")
    server.collectstatic()
    yield server
    server.stop()


def answered(participant_token):
    from studyapp.survey.models import Trial

    return set(
        Trial.objects.filter(participant__token=participant_token, answered_at__isnull=False)
        .values_list("pk", flat=True)
    )


def test_kill_9_mid_study_keeps_every_acknowledged_answer_and_sessions_resume(clips, server):
    from studyapp.survey.models import Participant as Row

    study = make_ranking_study(clips, trials_per_participant=4)
    server.start()
    bots = [Participant(server.url, study.slug, f"kill-{i}") for i in range(4)]
    for bot in bots:
        bot.enter()
        bot.consent()
        bot.start()
        bot.answer()
        bot.answer()
    acknowledged = {t for bot in bots for t, status, _ in bot.submits if status == 302}

    server.kill()  # master and workers, SIGKILL
    server.start()

    rows = Row.objects.filter(study=study)
    stored = set().union(*(answered(row.token) for row in rows))
    assert acknowledged <= stored and len(acknowledged) == 8
    for bot in bots:
        bot.close()
        bot.page = bot.get(bot.path())  # the old cookie resumes at the next trial
        assert bot.on_trial()
        while bot.on_trial():
            bot.answer()
        assert bot.at.endswith("/done/")
    assert all(row.completed_at for row in rows.all())
    assert sum(len(answered(row.token)) for row in rows) == 16


def test_kill_9_under_load_loses_no_acknowledged_answer_and_writes_nothing_half(clips, server):
    from studyapp.survey.models import Participant as Row
    from studyapp.survey.models import Trial, TrialItem

    study = make_ranking_study(clips, trials_per_participant=6)
    server.start()
    bots = [AsyncParticipant(server.url, study.slug, f"crowd-{i}") for i in range(16)]

    async def crowd():  # a bot cut off by the kill ends with its error
        await asyncio.gather(*(bot.run() for bot in bots), return_exceptions=True)

    def acknowledged():
        return {trial for bot in bots for trial, status, _ in bot.submits if status == 302}

    running = threading.Thread(target=asyncio.run, args=(crowd(),))
    running.start()
    deadline = time.monotonic() + 60
    while len(acknowledged()) < 20 and time.monotonic() < deadline:
        time.sleep(0.02)
    server.kill()  # with requests in flight
    running.join(60)
    before = acknowledged()
    assert 20 <= len(before) < 16 * 7  # killed mid-study

    def check_nothing_half_written():
        for trial in Trial.objects.filter(participant__study=study).prefetch_related("items"):
            ranks = sorted(item.answers.get("preference", 0) for item in trial.items.all())
            if trial.answered_at is None:
                assert ranks == [0, 0, 0], trial.pk
            elif trial.kind != Trial.Kind.PRACTICE:
                assert ranks == [1, 2, 3], trial.pk

    stored = set(Trial.objects.filter(participant__study=study, answered_at__isnull=False)
                 .values_list("pk", flat=True))
    assert before <= stored  # every acknowledged answer survived kill -9
    check_nothing_half_written()

    server.start()  # everyone comes back with their cookie and finishes
    # In a thread of its own: another test's browser may run an event loop in this one.
    again = threading.Thread(target=asyncio.run, args=(crowd(),))
    again.start()
    again.join(120)
    rows = Row.objects.filter(study=study)
    assert rows.count() == 16 and all(row.completed_at for row in rows)
    total = Trial.objects.filter(participant__study=study).count()
    assert Trial.objects.filter(participant__study=study, answered_at__isnull=False).count() == total
    assert acknowledged() <= set(Trial.objects.filter(participant__study=study)
                                 .values_list("pk", flat=True))
    check_nothing_half_written()
    assert TrialItem.objects.filter(trial__participant__study=study).count() == total * 3


def test_double_submit_concurrently_stores_one_answer(clips, server):
    from studyapp.survey.models import Trial, TrialItem

    study = make_ranking_study(clips, trials_per_participant=2)
    server.start()
    bot = Participant(server.url, study.slug, "double")
    bot.enter()
    bot.consent()
    bot.start()
    bot.watch()
    data = bot.answer_data()
    trial = int(data["trial"])
    statuses = []

    def submit():
        twin = Participant(server.url, study.slug, "double")
        twin.cookies, twin.page = dict(bot.cookies), bot.page
        statuses.append(twin.post(bot.path("trial"), data)[0])

    threads = [threading.Thread(target=submit) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert statuses == [302] * 6  # every copy is acknowledged: the answer is there once
    again = bot.post(bot.path("trial"), data)  # and once more, sequentially
    assert again[0] == 302
    row = Trial.objects.get(pk=trial)
    assert row.answered_at is not None
    answers = TrialItem.objects.filter(trial=row).values_list("answers", flat=True)
    assert sorted(a["preference"] for a in answers) == [1, 2, 3]
    assert Trial.objects.filter(participant=row.participant, answered_at__isnull=False).count() == 1


def test_database_unavailable_shows_503_page_and_writes_nothing(clips, make_bot, media_root,
                                                               settings, monkeypatch):
    from studyapp.survey.models import TrialItem

    assert "studyapp.survey.middleware.DatabaseUnavailableMiddleware" in settings.MIDDLEWARE
    study = make_ranking_study(clips)
    bot = make_bot(study)
    bot.join(PROLIFIC_PID="db-down")
    trial = bot.participant().current_trial()
    bot.trial_page()
    data = bot.answer_data(trial)

    # The connection breaks in the middle of storing the answer: after the trial row
    # is marked answered, before the ranks are written.
    def broken(execute, sql, params, many, context):
        if sql.startswith(f'UPDATE "{TrialItem._meta.db_table}"'):
            raise OperationalError("server closed the connection unexpectedly")
        return execute(sql, params, many, context)

    with connection.execute_wrapper(broken):
        response = bot.answer(data)
    assert response.status_code == 503
    assert b"The study is briefly unavailable" in response.content
    assert response["Retry-After"]
    trial.refresh_from_db()
    assert trial.answered_at is None  # the transaction rolled back: nothing half-written
    assert not TrialItem.objects.filter(trial=trial).exclude(answers={}).exists()

    assert bot.answer(data).status_code == 302  # back: the same answer goes through
    trial.refresh_from_db()
    assert trial.answered_at is not None


def test_database_unreachable_everywhere_is_503(clips, make_bot, media_root, settings, monkeypatch):
    assert "studyapp.survey.middleware.DatabaseUnavailableMiddleware" in settings.MIDDLEWARE
    study = make_ranking_study(clips)
    bot = make_bot(study)
    bot.join(PROLIFIC_PID="db-gone")

    def refuse(*args, **kwargs):
        raise OperationalError("connection refused")

    from django.db.backends.base.base import BaseDatabaseWrapper

    connection.close()
    monkeypatch.setattr(BaseDatabaseWrapper, "ensure_connection", refuse)
    response = bot.trial_page(watch=False)
    assert response.status_code == 503
    assert b"briefly unavailable" in response.content


def test_server_error_handler_maps_database_errors_to_503(rf):
    import sys

    from studyapp.survey.middleware import server_error

    try:
        raise OperationalError("gone")
    except OperationalError:
        assert sys.exc_info()[0] is OperationalError
        assert server_error(rf.get("/")).status_code == 503


@pytest.mark.skipif(not redis_up(), reason="no Redis on 127.0.0.1:6379")
def test_entry_rate_limit_is_shared_by_every_worker_through_redis(clips, tmp_path, media_root):
    # Two gunicorn workers, twelve people at once from one address: with the
    # per-process cache each worker would let 4 through; with STUDY_CACHE_URL it is 4
    # in all (an atomic count in Redis).
    study = make_ranking_study(clips)
    cache_url = f"redis://127.0.0.1:6379/{8 + os.getpid() % 7}"
    redis.Redis.from_url(cache_url).flushdb()
    env = server_env(database_url(), tmp_path / "var", STUDY_CACHE_URL=cache_url,
                     STUDY_ENTRY_RATE_LIMIT="4/h")
    server = Server(env, workers=2, settings="benchmarks.loadtest_settings",
                    log=tmp_path / "gunicorn.log")
    server.collectstatic()
    with server:
        statuses = []
        ready = threading.Barrier(12)

        def enter(i):  # at once, so that both workers answer some
            bot = Participant(server.url, study.slug, f"limited-{i}")
            ready.wait(10)
            statuses.append(bot.request("GET", bot.path() + f"?PROLIFIC_PID=limited-{i}")[0])
            bot.close()

        threads = [threading.Thread(target=enter, args=(i,)) for i in range(12)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
    redis.Redis.from_url(cache_url).flushdb()
    assert sorted(statuses) == [302] * 4 + [429] * 8, statuses
