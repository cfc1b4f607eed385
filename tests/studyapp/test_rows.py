"""The answer path's written-out statements (studyapp/survey/models/rows.py) read and write
what the ORM would: the same field values, converted as the ORM converts them."""

from datetime import timedelta

from django.utils import timezone

from studyapp.survey.models import Participant, Stimulus, Trial, TrialItem


def field_values(instance) -> dict:
    return {field.attname: getattr(instance, field.attname)
            for field in type(instance)._meta.concrete_fields}


def started(ranking_study, make_bot, pid="rows"):
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID=pid)
    return bot, bot.participant()


def test_trials_of_reads_what_the_orm_reads(ranking_study, make_bot):
    bot, participant = started(ranking_study, make_bot)
    first, second = participant.trials.order_by("index")[:2]
    # Values of every kind the rows hold: JSON, datetimes, booleans, nulls.
    Trial.objects.filter(pk=first.pk).update(
        shown_at=timezone.now() - timedelta(seconds=3), events=[[5, "play", 0]],
        answers={"preference": "left"}, catch_passed=False)
    TrialItem.objects.filter(trial=first, position=0).update(
        fetched={"mp4": [[0, 99]]}, fetched_at=timezone.now(), plays=2, required=False)
    found = TrialItem.objects.trials_of(participant, first.pk, and_next=True)
    assert [trial.pk for trial, _ in found] == [first.pk, second.pk]
    for trial, items in found:
        orm = (TrialItem.objects.filter(trial=trial).select_related("trial", "stimulus")
               .order_by("position"))
        assert [item.pk for item in items] == [item.pk for item in orm]
        assert field_values(trial) == field_values(orm[0].trial)
        for item, expected in zip(items, orm):
            assert field_values(item) == field_values(expected)
            assert field_values(item.stimulus) == field_values(expected.stimulus)
            assert isinstance(item.stimulus, Stimulus) and item.trial is trial
            assert not item._state.adding
        assert trial.participant is participant
    assert isinstance(found[0][0].shown_at, type(timezone.now()))
    assert found[0][0].events == [[5, "play", 0]] and found[0][0].catch_passed is False
    # Without and_next, the trial alone; a trial of another participant is not there.
    assert [t.pk for t, _ in TrialItem.objects.trials_of(participant, first.pk)] == [first.pk]
    _, other = started(ranking_study, make_bot, pid="someone-else")
    assert TrialItem.objects.trials_of(other, first.pk, and_next=True) == []
    # An answered next trial is not read as the one to show next.
    Trial.objects.filter(pk=second.pk).update(answered_at=timezone.now())
    assert [t.pk for t, _ in TrialItem.objects.trials_of(participant, first.pk, and_next=True)] \
        == [first.pk]


def test_by_token_reads_what_the_orm_reads(ranking_study, make_bot):
    _, participant = started(ranking_study, make_bot)
    read = Participant.objects.by_token(ranking_study, participant.token)
    assert field_values(read) == field_values(Participant.objects.get(pk=participant.pk))
    assert read.study_version == type(ranking_study).objects.get(pk=ranking_study.pk).version


def test_find_and_the_study_lock_read_what_the_orm_reads(ranking_study, make_bot):
    import pytest
    from django.db import transaction

    from studyapp.survey.models import Study

    _, participant = started(ranking_study, make_bot, pid="found")
    found = Participant.objects.find(ranking_study, participant.external_key)
    assert field_values(found) == field_values(Participant.objects.get(pk=participant.pk))
    assert Participant.objects.find(ranking_study, "nobody") is None
    assert Participant.objects.find(ranking_study, "") is None
    with transaction.atomic():
        locked = Study.objects.lock(ranking_study.pk)
        assert field_values(locked) == field_values(Study.objects.get(pk=ranking_study.pk))
        assert type(locked.kind) is type(ranking_study.kind)
        with pytest.raises(Study.DoesNotExist):
            Study.objects.lock(ranking_study.pk + 1000)


def test_an_answer_writes_its_items_and_fetches_in_one_executemany(ranking_study, make_bot):
    from django.db import connection
    from django.test.utils import CaptureQueriesContext

    from studyapp.participation.answers import Answer

    bot, participant = started(ranking_study, make_bot)
    trial = participant.current_trial()
    bot.trial_page()
    participant = Participant.objects.by_token(ranking_study, participant.token)
    participant.study = ranking_study
    (trial, items), following = TrialItem.objects.trials_of(participant, trial.pk, and_next=True)
    participant.following = following
    answer = Answer(items={item.pk: {"preference": rank} for rank, item in enumerate(items, 1)},
                    plays={item.pk: 1 for item in items}, events=[[1, "play", 0]])

    def fetches(items):  # as fetch_log.merged does, after locking the rows
        assert TrialItem.objects.lock_fetches(items).keys() == {item.pk for item in items}
        for item in items:
            item.fetched, item.fetched_at = {"mp4": [[0, 9]]}, timezone.now()
        return True

    with CaptureQueriesContext(connection) as captured:
        assert Trial.objects.record_answer(trial, answer, items, fetches=fetches)
    item_updates = [q["sql"] for q in captured.captured_queries
                    if q["sql"].startswith(f'{len(items)} times: UPDATE "survey_trialitem"')
                    or q["sql"].startswith('UPDATE "survey_trialitem"')]
    assert len(item_updates) == 1, item_updates
    for item in TrialItem.objects.filter(trial=trial).order_by("position"):
        assert item.answers == {"preference": item.position + 1} and item.plays == 1
        assert item.fetched == {"mp4": [[0, 9]]} and item.fetched_at is not None
    trial.refresh_from_db()
    assert trial.answered_at is not None and trial.events == [[1, "play", 0]]
    assert Participant.objects.get(pk=participant.pk).active_at == participant.active_at
    # The same answer again stores nothing and says so.
    assert not Trial.objects.record_answer(trial, answer, items)


def test_on_postgresql_the_statements_are_prepared_once_per_connection(
        transactional_db, ranking_study, make_bot, settings):
    import re

    import pytest
    from django.db import connection

    from studyapp.survey.models.rows import Statements

    if connection.vendor != "postgresql":
        pytest.skip("prepared statements are PostgreSQL's")
    connection.close()  # a new connection: nothing prepared on it by an earlier test

    def prepared_here() -> list[str]:
        with connection.cursor() as cursor:
            cursor.execute("SELECT statement FROM pg_prepared_statements")
            return [row[0] for row in cursor.fetchall()]

    def shape(sql: str) -> str:  # placeholders and IN lists alike, whatever their style
        return re.sub(r"IN \([^)]*\)", "IN (?)", re.sub(r"%s|\$\d+", "?", sql))

    settings.STUDY_PREPARED_STATEMENTS = False  # as behind an old PgBouncer
    bot, participant = started(ranking_study, make_bot)
    bot.trial_page()
    Participant.objects.by_token(ranking_study, participant.token)
    assert prepared_here() == []
    settings.STUDY_PREPARED_STATEMENTS = True
    for _ in range(3):  # the same answers every time
        read = Participant.objects.by_token(ranking_study, participant.token)
        assert read.pk == participant.pk and read.n_trials == participant.trials.count()
    found = [sql for sql in prepared_here() if 'FROM "survey_participant" p' in sql]
    assert len(found) == 1 and "$1" in found[0]
    # A whole session through the pages (consent and start: the ORM's INSERTs and
    # queries; every answer: the written-out statements): only those are prepared.
    other = make_bot(ranking_study)
    other.join(PROLIFIC_PID="prepared")
    while (trial := other.participant().current_trial()) is not None:
        other.trial_page()
        assert other.answer(other.answer_data(trial)).status_code == 302
    ours = {shape(text) for statement in Statements.every for text in statement.kept.values()}
    prepared = prepared_here()
    assert len(prepared) > 3, prepared
    assert all(shape(sql) in ours for sql in prepared), \
        [sql for sql in prepared if shape(sql) not in ours]
