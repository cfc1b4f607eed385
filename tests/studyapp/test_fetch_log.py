"""A clip sent to its last byte is on record before anyone can answer: a witness no database
lock holds up (a spool file, or Redis), folded into the database on the answer."""

import threading
import time
import uuid

import pytest
from django.db import OperationalError

from studyapp.participation import fetch_log
from studyapp.survey.models import Trial, TrialItem

pytestmark = pytest.mark.django_db


@pytest.fixture
def spool(settings, tmp_path):
    settings.STUDY_FETCH_LOG_URL = ""
    settings.STUDY_FETCH_SPOOL = tmp_path / "fetches"
    return settings.STUDY_FETCH_SPOOL


@pytest.fixture
def redis_log(settings, tmp_path):
    redis = pytest.importorskip("redis")
    url = "redis://127.0.0.1:6379/15"
    try:
        redis.Redis.from_url(url, socket_timeout=1).ping()
    except redis.RedisError:
        pytest.skip("no Redis at 127.0.0.1:6379")
    settings.STUDY_FETCH_LOG_URL = url
    settings.STUDY_FETCH_LOG_PREFIX = f"test-{uuid.uuid4().hex}:"
    settings.STUDY_FETCH_SPOOL = tmp_path / "fetches"
    settings.STUDY_FETCH_FLUSH_S = 0  # the test flushes itself
    store = fetch_log.backend()
    yield store
    keys = list(store.client.scan_iter(settings.STUDY_FETCH_LOG_PREFIX + "*"))
    if keys:
        store.client.delete(*keys)


@pytest.fixture
def watching(settings):
    settings.STUDY_WATCH_TIME_FACTOR = 1.0


@pytest.fixture
def locked(monkeypatch, settings):
    """The database write of a fetch never gets the lock (SQLite's queue, timed out)."""
    settings.STUDY_FETCH_FLUSH_S = 0  # no flushing thread: the test looks at the witnesses

    def record_fetch(*args, **kwargs):
        raise OperationalError("database is locked")

    monkeypatch.setattr(TrialItem.objects, "record_fetch", record_fetch)


def test_fold_merges_ranges_and_takes_the_witness_time():
    half = fetch_log.make_line("mp4", 0, 499, 1000, at=100.0)
    rest = fetch_log.make_line("mp4", 500, 999, 1000, at=101.5)
    fetched, at, changed = fetch_log.fold({}, None, [rest, half])
    assert changed and fetched == {"mp4": [[0, 999]]} and at.timestamp() == 101.5
    assert fetch_log.fold({"mp4": [[0, 999]]}, at, [rest])[2] is False  # already whole
    fetched, at, changed = fetch_log.fold({}, None, [half, "mp4 torn"])
    assert changed and fetched == {"mp4": [[0, 499]]} and at is None


def test_spool_appends_and_removes_only_what_was_folded(spool):
    store = fetch_log.backend()
    assert isinstance(store, fetch_log.SpoolLog)
    a, b = fetch_log.make_line("mp4", 0, 9, 10), fetch_log.make_line("mp4", 0, 4, 10)
    store.append("tok", a)
    store.append("tok", b)
    assert store.read(["tok", "other"]) == {"tok": [a, b]}
    store.remove("tok", [a])
    assert store.read(["tok"]) == {"tok": [b]}
    store.remove("tok", [b])
    assert store.read(["tok"]) == {} and store.tokens() == []
    # Appends from many threads while lines are removed: none is lost.
    lines = [fetch_log.make_line("mp4", 0, i, 100) for i in range(200)]

    def add(part):
        for line in part:
            store.append("busy", line)

    threads = [threading.Thread(target=add, args=(lines[i::4],)) for i in range(4)]
    for thread in threads:
        thread.start()
    removed = []
    while any(t.is_alive() for t in threads) or store.read(["busy"]):
        seen = store.read(["busy"]).get("busy", [])[:7]
        store.remove("busy", seen)
        removed += seen
    assert sorted(removed) == sorted(lines)


def test_a_fetch_whose_database_write_lags_still_lets_the_answer_in(
        ranking_study, make_bot, spool, locked, watching, django_capture_on_commit_callbacks):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()  # every clip fetched whole; no database write got through
    items = list(trial.items.select_related("stimulus"))
    assert not TrialItem.objects.filter(trial=trial, fetched_at__isnull=False).exists()
    assert sorted(fetch_log.backend().tokens()) == sorted(i.token for i in items)
    time.sleep(max(i.stimulus.duration for i in items))
    with django_capture_on_commit_callbacks(execute=True):
        assert bot.answer(bot.answer_data(trial)).status_code == 302
    assert Trial.objects.get(pk=trial.pk).answered_at is not None
    # The answer wrote the fetches (with the witnesses' times) and dropped the witnesses.
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert all(i.fetched["mp4"] for i in TrialItem.objects.filter(trial=trial))
    assert fetch_log.backend().tokens() == []


def test_a_witness_of_part_of_a_clip_is_not_a_whole_fetch(ranking_study, make_bot, spool,
                                                          locked, watching):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page(watch=False)
    items = list(trial.items.select_related("stimulus").order_by("position"))
    for item in items:
        response = bot.client.get(item.clip_url(), HTTP_RANGE="bytes=0-99")
        b"".join(response.streaming_content)
    time.sleep(max(i.stimulus.duration for i in items))
    refused = bot.answer(bot.answer_data(trial))
    assert refused.status_code == 400 and b"has not been loaded to its end yet" in refused.content
    assert Trial.objects.get(pk=trial.pk).answered_at is None


def test_without_a_lag_the_database_is_written_at_once_and_the_spool_stays_empty(
        ranking_study, make_bot, spool):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert fetch_log.backend().tokens() == []


def test_with_redis_fetches_wait_there_and_the_answer_writes_them_in_one_go(
        ranking_study, make_bot, redis_log, watching, django_capture_on_commit_callbacks):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    items = list(trial.items.select_related("stimulus"))
    # Nothing went to the database: the witnesses are in Redis (they outlive the worker).
    assert not TrialItem.objects.filter(trial=trial, fetched_at__isnull=False).exists()
    assert sorted(redis_log.tokens()) == sorted(i.token for i in items)
    time.sleep(max(i.stimulus.duration for i in items))
    with django_capture_on_commit_callbacks(execute=True):
        assert bot.answer(bot.answer_data(trial)).status_code == 302
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert redis_log.tokens() == []


def test_with_redis_a_flush_writes_what_no_answer_did(ranking_study, make_bot, redis_log):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()  # fetched, never answered (the participant left)
    fetch_log._backend_for = None  # another process: only Redis knows
    assert fetch_log.flush() == trial.items.count()
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert fetch_log.backend().tokens() == []
    assert fetch_log.flush() == 0


def test_when_redis_does_not_answer_the_spool_and_database_do(ranking_study, make_bot, settings,
                                                               tmp_path):
    pytest.importorskip("redis")
    settings.STUDY_FETCH_LOG_URL = "redis://127.0.0.1:1/0"  # nothing listens there
    settings.STUDY_FETCH_SPOOL = tmp_path / "fetches"
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert bot.answer(bot.answer_data(trial)).status_code == 302


def test_flush_fetches_writes_the_witnesses_no_answer_came_for(ranking_study, make_bot, spool,
                                                                locked, monkeypatch):
    from io import StringIO

    from django.core.management import call_command

    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()  # fetched whole, the database writes failed, no answer
    monkeypatch.undo()  # the database takes writes again
    out = StringIO()
    call_command("flush_fetches", stdout=out)
    assert out.getvalue().startswith(f"{trial.items.count()} trial items updated")
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert fetch_log.backend().tokens() == []


@pytest.mark.django_db(transaction=True)
def test_on_sqlite_a_fetch_does_not_queue_for_the_write_lock(ranking_study, make_bot, spool,
                                                             settings):
    import sqlite3

    from django.db import connection

    if connection.vendor != "sqlite":
        pytest.skip("SQLite's one write lock")
    settings.STUDY_FETCH_FLUSH_S = 0
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page(watch=False)
    other = sqlite3.connect(connection.settings_dict["NAME"], isolation_level=None)
    other.execute("BEGIN IMMEDIATE")  # another participant's long write
    try:
        begun = time.monotonic()
        bot.watch(trial)
        took = time.monotonic() - begun
    finally:
        other.execute("ROLLBACK")
        other.close()
    assert took < 5  # not the connection's 30 s a fetch, per clip
    assert not TrialItem.objects.filter(trial=trial, fetched_at__isnull=False).exists()
    assert len(fetch_log.backend().tokens()) == trial.items.count()
    assert bot.answer(bot.answer_data(trial)).status_code == 302
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert fetch_log.backend().tokens() == []
    with connection.cursor() as cursor:  # the connection's own wait is back
        assert cursor.execute("PRAGMA busy_timeout").fetchone()[0] == 30000


def test_the_witness_is_written_before_the_last_chunk_and_withdrawn_if_it_is_not_taken(
        ranking_study, make_bot, spool, locked):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page(watch=False)
    item = trial.items.first()
    response = bot.client.get(item.clip_url())
    chunks = iter(response.streaming_content)
    next(chunks)  # the test clips are one chunk: the last one, not taken yet
    assert fetch_log.backend().tokens() == [item.token]  # on record before the client has it
    response.close()  # the client went away: the server never took it
    assert fetch_log.backend().tokens() == []


def test_without_a_writable_spool_the_database_write_alone_records_the_fetch(
        ranking_study, make_bot, settings, tmp_path):
    (tmp_path / "a-file").write_text("")
    settings.STUDY_FETCH_LOG_URL = ""
    settings.STUDY_FETCH_SPOOL = tmp_path / "a-file" / "fetches"  # cannot be made
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    assert not TrialItem.objects.filter(trial=trial, fetched_at=None).exists()
    assert bot.answer(bot.answer_data(trial)).status_code == 302
