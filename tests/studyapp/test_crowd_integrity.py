"""Crowd integrity: what an adversarial participant or bot tries, and that it no longer
gets through. Codes only ever of the participant's own outcome; Prolific's ids checked,
stored and unique; places held only by people who are really there; entry floods and
wrong admin passwords throttled, also without a working cache."""

from datetime import timedelta

import pytest
from django.contrib.auth.models import User
from django.core.exceptions import ValidationError
from django.test import Client
from django.utils import timezone

from studyapp.crowd.platform import make_platform
from studyapp.crowd.platforms.prolific import prolific_minimum_time, prolific_time_limit
from studyapp.survey.models import FailedLogin, Participant, Stimulus, Study, Trial
from studyapp.stimuli.config import ConfigError, parse
from tests.studyapp.conftest import make_stimuli, make_study

pytestmark = pytest.mark.django_db

STUDY_ID = "60aaca280709ee40ec37d488"
CODES = {"completed": "C0MPL3TE", "failed_attention": "FA1LED00", "no_consent": "N0C0NSNT"}
PROLIFIC = {"platform": "prolific", "codes": CODES, "prolific_study_id": STUDY_ID}


def ids(pid, session=None, study=STUDY_ID):
    return {"PROLIFIC_PID": pid, "STUDY_ID": study, "SESSION_ID": session or pid[::-1]}


@pytest.fixture
def on_prolific(media_root, clips, extra_clips):
    return make_study("ranking", clips, extra_clips, slug="integrity", catch=True,
                      instructed_checks=1, crowd=PROLIFIC)


def fail_every_check(bot):
    """Answer every trial; give each attention check an answer that fails it."""
    while (trial := bot.participant().current_trial()) is not None:
        bot.trial_page()
        data = bot.answer_data(trial)
        if trial.kind == Trial.Kind.CATCH:  # the broken clip ranked first
            broken = trial.items.get(stimulus__role="catch")
            data = bot.answer_data(trial, ranks=swap_first(trial, broken.position))
        elif trial.kind == Trial.Kind.INSTRUCTED:
            asked = trial.instruction
            wrong = asked["rank"] % 3 + 1  # another rank for the clip asked about
            data = bot.answer_data(trial, ranks=with_rank(asked["position"], wrong))
        response = bot.answer(data, follow=True)
    return response


def swap_first(trial, position):
    ranks = {p: p + 1 for p in range(3)}
    ranks[position], ranks[0] = 1, ranks[position]
    return ranks


def with_rank(position, rank):
    others = iter(r for r in (1, 2, 3) if r != rank)
    return {p: rank if p == position else next(others) for p in range(3)}


def small_config(tmp_path, **study):
    return parse({"slug": "tiny", "title": "Movement study", "dataset": "demo",
                  "sources": ["real"], "study": {"type": "ranking", **study}}, tmp_path)


# 1. Codes: only ever the participant's own outcome's


def test_a_failed_participant_gets_the_failed_code_never_the_completed_one(on_prolific,
                                                                          make_bot):
    bot = make_bot(on_prolific)
    bot.enter(**ids("a" * 24))
    bot.consent()
    bot.start()
    page = fail_every_check(bot).content.decode()
    person = bot.participant()
    assert person.outcome == "failed_attention" and person.completion_code == "FA1LED00"
    assert "C0MPL3TE" not in page and "cc=FA1LED00" in page


def test_a_prolific_study_without_a_code_of_an_outcome_it_can_end_with_is_refused(tmp_path,
                                                                                 admin_client):
    only_completed = {"platform": "prolific", "codes": {"completed": "C1", "no_consent": "N1"}}
    with pytest.raises(ConfigError, match=r"study\.crowd\.codes\.failed_attention: this study "
                                          r"has 1 attention check"):
        small_config(tmp_path, catch_trials=1, crowd=only_completed)
    # Without a word about checks, a Prolific study over 5 minutes gets two instructed
    # checks (its policy), so it needs the code too; the error says so.
    with pytest.raises(ConfigError, match="instructed_checks defaults to 2"):
        small_config(tmp_path, crowd=only_completed)
    with pytest.raises(ConfigError, match=r"crowd\.codes\.no_consent: a participant can decline"):
        small_config(tmp_path, catch_trials=0, crowd={"platform": "prolific",
                                                      "codes": {"completed": "C1"}})
    screening = {**PROLIFIC, "screening": [{"question": "Can you see the clips?"}]}
    with pytest.raises(ConfigError, match=r"crowd\.codes\.screened_out: this study has "
                                          r"screening questions"):
        small_config(tmp_path, crowd=screening)
    assert small_config(tmp_path, crowd=PROLIFIC).study_options["instructed_checks"] == 2
    with pytest.raises(ValidationError, match=r"crowd\.codes\.failed_attention"):
        Study.objects.create_study("ranking", "no-code", "Movement study", catch_trials=1,
                                   crowd=only_completed)
    # The admin refuses it with the error on the crowd field.
    study = Study.objects.create_study("ranking", "in-admin", "Movement study", crowd=PROLIFIC)
    form = admin_client.get(f"/admin/survey/study/{study.pk}/change/").context["adminform"].form
    data = {name: value for name, value in form.initial.items() if value is not None}
    data.update(crowd='{"platform": "prolific", "codes": {"completed": "C1", '
                      '"no_consent": "N1"}}', instructed_checks=2, criteria="[]", options="{}",
                status="open", study_type="ranking",
                **{f"standards-{k}": v for k, v in
                   (("TOTAL_FORMS", 0), ("INITIAL_FORMS", 0), ("MIN_NUM_FORMS", 0),
                    ("MAX_NUM_FORMS", 1000))})
    response = admin_client.post(f"/admin/survey/study/{study.pk}/change/", data)
    assert response.status_code == 200  # the form again, with its error
    assert "crowd.codes.failed_attention" in response.content.decode()
    study.refresh_from_db()
    assert study.instructed_checks == 0


def test_without_its_own_code_a_failed_outcome_gets_no_code_and_no_link(media_root, clips,
                                                                        make_bot):
    """Elsewhere than Prolific a failed outcome without a code of its own gets none: not
    the completed one, not a random one, no link to a completion URL that may credit."""
    crowd = {"platform": "generic", "id_param": "participantId",
             "completion_url_template": "https://panel.example/credit?id={id}",
             "codes": {"completed": "DONE1234"}}
    study = make_study("ranking", clips, slug="panel", crowd=crowd, max_failed_catch=0,
                       instructed_checks=1)
    bot = make_bot(study)
    bot.join(participantId="w-1")
    page = fail_every_check(bot).content.decode()
    person = bot.participant()
    assert person.outcome == "failed_attention" and person.completion_code == ""
    assert "panel.example" not in page and "DONE1234" not in page
    assert "ends without a completion code" in page
    # A Prolific study whose code was removed behind the admin's back: still no code.
    Study.objects.filter(pk=study.pk).update(crowd={"platform": "prolific", "codes": {
        "completed": "C1"}, "strict_ids": False})
    assert Study.objects.get(pk=study.pk).platform.code_for("failed_attention") == ""
    with pytest.raises(ValueError, match="timed_out: a participant who runs out of time gets "
                                         "no code"):
        make_platform({**PROLIFIC, "codes": {**CODES, "timed_out": "T1"}})


# 2. Ids: the study's own, well-formed, one session once


def test_a_link_for_another_study_or_with_made_up_ids_is_refused(on_prolific, make_bot):
    cases = [
        (ids("a" * 24, study="b" * 24), 400, b"This link is for another study"),
        ({**ids("a" * 24), "SESSION_ID": ""}, 400, b"carries your id (SESSION_ID)"),
        ({**ids("a" * 24), "SESSION_ID": "session-1"}, 400, b"(SESSION_ID) is not one"),
        ({"PROLIFIC_PID": "a" * 24}, 400, b"(STUDY_ID)"),
    ]
    for query, status, text in cases:
        bot = make_bot(on_prolific)
        response = bot.enter(**query)
        assert response.status_code == status and text in response.content, query
        assert b"missing your participant id" in bot.consent().content  # consent directly
    assert not Participant.objects.exists()
    bot = make_bot(on_prolific)
    bot.join(**ids("a" * 24, "c" * 24))
    assert bot.participant().external_ids == ids("a" * 24, "c" * 24)


def test_one_session_takes_the_study_once(on_prolific, make_bot):
    first = make_bot(on_prolific)
    first.join(**ids("a" * 24, "c" * 24))
    second = make_bot(on_prolific)  # another made-up person id, the same session
    refused = second.enter(**ids("b" * 24, "c" * 24))
    assert refused.status_code == 403 and b"session has already been used" in refused.content
    assert b"session has already been used" in second.consent().content  # consent directly
    assert Participant.objects.count() == 1


def test_a_failed_participant_cannot_start_again_under_a_made_up_id(on_prolific, make_bot):
    bot = make_bot(on_prolific)
    bot.join(**ids("a" * 24))
    fail_every_check(bot)
    again = bot.enter(**ids("f" * 24))  # the same browser, a new id and session
    assert again.status_code == 403 and b"This browser has already taken part" in again.content
    assert Participant.objects.count() == 1


def test_strict_ids_can_be_turned_off(media_root, clips, make_bot):
    loose = {**PROLIFIC, "strict_ids": False}
    study = make_study("ranking", clips, slug="loose", crowd=loose, instructed_checks=0)
    bot = make_bot(study)
    assert bot.enter(PROLIFIC_PID="a" * 24, STUDY_ID=STUDY_ID).status_code == 200
    assert bot.enter(PROLIFIC_PID="a" * 24).status_code == 400  # still the study's own id
    generic = make_platform({"platform": "generic", "id_param": "pid", "strict_ids": True,
                             "extra_params": ["session"]})
    assert generic.read_ids({"pid": "w-1", "session": "s.2"})[1] == "pid:w-1"
    with pytest.raises(Exception, match="session"):
        generic.read_ids({"pid": "w-1"})
    with pytest.raises(Exception, match="pid"):
        generic.read_ids({"pid": "<w>", "session": "s"})


# 3. Attention checks as Prolific allows them


def test_one_failed_check_is_forgiven_two_fail(media_root, clips, extra_clips, make_bot):
    assert Study._meta.get_field("max_failed_catch").default == 1
    study = make_study("ranking", clips, extra_clips, slug="two-checks", catch=True,
                       instructed_checks=1)
    assert study.max_failed_catch == 1
    both = make_bot(study)
    both.join()
    fail_every_check(both)
    assert both.participant().outcome == "failed_attention"
    one = make_bot(study)
    one.join()
    while (trial := one.participant().current_trial()) is not None:
        one.trial_page()
        ranks = None
        if trial.kind == Trial.Kind.INSTRUCTED:  # failed; the catch trial is passed
            ranks = with_rank(trial.instruction["position"], trial.instruction["rank"] % 3 + 1)
        elif trial.kind == Trial.Kind.CATCH:
            broken = trial.items.get(stimulus__role="catch").position
            ranks = with_rank(broken, 3)
        one.answer(one.answer_data(trial, ranks=ranks))
    assert one.participant().outcome == "completed"
    assert list(Trial.objects.filter(participant=one.participant(), kind__in=Trial.CHECK_KINDS)
                .order_by("kind").values_list("kind", "catch_passed")) == [
        ("catch", True), ("instructed", False)]


def test_a_prolific_study_over_five_minutes_is_warned_about_too_few_checks(tmp_path,
                                                                          admin_client):
    # Before its build a config that leaves the trials to the data is estimated at 10
    # trials of 3-second clips (studyapp.participation.duration): 8 minutes for ranking 6 clips.
    config = small_config(tmp_path, catch_trials=1, instructed_checks=0, crowd=PROLIFIC)
    assert config.warnings == ["study: 1 attention check(s) in a study estimated at 8 minutes; "
                               "Prolific asks for at least 2 in a study over 5 minutes (set "
                               "study.instructed_checks or catch_trials)"]
    lenient = small_config(tmp_path, max_failed_catch=0, crowd=PROLIFIC)
    assert "Prolific allows a rejection only after 2" in lenient.warnings[0]
    assert small_config(tmp_path, crowd=PROLIFIC).warnings == []
    assert small_config(tmp_path, catch_trials=1).warnings == []  # no platform: no policy
    assert small_config(tmp_path, catch_trials=1, instructed_checks=0, crowd=PROLIFIC,
                        trials_per_participant=2).warnings == []  # 2 minutes: no policy
    study = Study.objects.create_study("ranking", "few", "Movement study", catch_trials=1,
                                       crowd=PROLIFIC)
    assert study.crowd_warnings() == []  # no clips yet: about a minute
    study.trials_per_participant = 20
    make_stimuli(study, actions=[f"action{k}" for k in range(20)])
    Stimulus.objects.filter(study=study).update(duration=3.0)
    assert study.minutes() > 5 and study.crowd_warnings() == [
        config.warnings[0].replace("8 minutes", f"{study.minutes()} minutes")]


# 4. Places: held only by people who are really there


def test_consent_and_leave_holds_a_place_only_until_idle(on_prolific, make_bot):
    Study.objects.filter(pk=on_prolific.pk).update(max_participants=1)
    leaver = make_bot(on_prolific)
    leaver.join(**ids("a" * 24))
    newcomer = make_bot(on_prolific)
    assert b"This study is full" in newcomer.enter(**ids("b" * 24)).content
    person = leaver.participant()
    person.refresh_from_db()
    assert person.active_at == person.consented_at
    # Answering keeps the place: the idle clock starts again.
    trial = person.current_trial()
    leaver.trial_page()
    leaver.answer(leaver.answer_data(trial))
    person.refresh_from_db()
    assert person.active_at > person.consented_at
    Participant.objects.filter(pk=person.pk).update(
        active_at=timezone.now() - timedelta(minutes=9))
    assert b"This study is full" in newcomer.enter(**ids("b" * 24)).content
    Participant.objects.filter(pk=person.pk).update(
        active_at=timezone.now() - timedelta(minutes=11))  # idle past idle_minutes (10)
    newcomer.enter(**ids("b" * 24))
    newcomer.consent()
    assert Participant.objects.filter(external_key__endswith="b" * 24).exists()
    person.refresh_from_db()
    assert (person.outcome, person.completion_code, person.completed_at) == ("timed_out", "",
                                                                              None)
    late = leaver.client.get(leaver.url("trial"))
    assert late.status_code == 410 and b"time for this study has run out" in late.content
    assert b"run out" in leaver.enter(**ids("a" * 24)).content


def test_idle_places_are_released_when_counted_without_a_daemon(on_prolific):
    long_ago = timezone.now() - timedelta(minutes=11)
    for i, when in enumerate((long_ago, timezone.now())):
        Participant.objects.create(study=on_prolific, seed=i, external_key=f"k{i}",
                                   consented_at=when, active_at=when)
    legacy = Participant.objects.create(study=on_prolific, seed=3, external_key="old",
                                        consented_at=long_ago)  # no active_at: since consent
    assert Participant.objects.holding_a_place(on_prolific).count() == 1
    assert Participant.objects.release_places(on_prolific) == 2
    legacy.refresh_from_db()
    assert legacy.outcome == "timed_out" and legacy.timed_out()
    on_prolific.crowd = {**PROLIFIC, "idle_minutes": None}
    on_prolific.save()
    assert on_prolific.idle_limit() is None


def test_a_prolific_study_has_a_time_limit_by_default(on_prolific):
    minutes = on_prolific.minutes()  # estimated from its trials and clips
    assert on_prolific.time_limit() == timedelta(minutes=prolific_time_limit(minutes))
    assert prolific_time_limit(10) == 30 and prolific_time_limit(1) == prolific_minimum_time(1) == 5
    on_prolific.crowd = {**PROLIFIC, "time_limit_minutes": None}
    assert on_prolific.time_limit() is None
    on_prolific.crowd = {}
    assert on_prolific.time_limit() is None  # no platform: no default


# 5. Rate limits


def test_one_address_cannot_fill_one_study(on_prolific, media_root, clips, settings):
    settings.STUDY_ENTRY_RATE_LIMIT_PER_STUDY = "3/h"
    statuses = []
    for i in range(5):
        client = Client()
        client.get(f"/s/{on_prolific.slug}/", ids(f"{i:x}" * 24))
        statuses.append(client.post(f"/s/{on_prolific.slug}/consent/", {"agree": "1"})
                        .status_code)
    assert statuses == [302] * 3 + [429] * 2
    assert Participant.objects.filter(study=on_prolific).count() == 3
    other_study = make_study("ranking", clips, slug="another")
    assert Client().post(f"/s/{other_study.slug}/consent/", {"agree": "1"}).status_code == 302
    elsewhere = Client(REMOTE_ADDR="10.0.0.9")
    elsewhere.get(f"/s/{on_prolific.slug}/", ids("e" * 24))
    assert elsewhere.post(f"/s/{on_prolific.slug}/consent/", {"agree": "1"}).status_code == 302


@pytest.mark.parametrize("cache", ["redis down", "per process"])
def test_the_admin_login_throttle_holds_without_a_working_cache(settings, cache):
    from django.core.cache import cache as default_cache

    settings.STUDY_LOGIN_RATE_LIMIT = "3/h"
    if cache == "redis down":
        settings.CACHES = {"default": {"BACKEND": "django.core.cache.backends.redis.RedisCache",
                                       "LOCATION": "redis://127.0.0.1:9/0"}}  # nothing listens
    User.objects.create_superuser("admin", "", "right-password")
    statuses = []
    for i in range(5):
        if cache == "per process":
            default_cache.clear()  # each request a worker of its own: nothing shared there
        statuses.append(Client().post("/admin/login/", {"username": "admin",
                                                        "password": f"guess{i}"}).status_code)
    assert statuses == [200] * 3 + [429] * 2
    refused = Client().post("/admin/login/", {"username": "admin", "password": "right-password"})
    assert refused.status_code == 429 and b"Too many failed logins" in refused.content
    assert FailedLogin.objects.count() == 3
    old = timezone.now() - timedelta(days=2)
    FailedLogin.objects.record("10.0.0.1", now=old)
    FailedLogin.objects.record("10.0.0.1")  # forgets what is older than a day
    assert not FailedLogin.objects.filter(failed_at__lt=timezone.now() - timedelta(days=1)).exists()


def test_a_consent_to_a_study_with_places_works_its_minutes_out_once(on_prolific, monkeypatch):
    # Prolific's default time limit comes from the study's minutes (a session planned,
    # every completion read); with places, a consent releases the lapsed places and counts
    # the rest, with the study's row locked: the minutes are worked out once for both.
    Study.objects.filter(pk=on_prolific.pk).update(max_participants=10)
    calls = []
    duration = Study.duration
    monkeypatch.setattr(Study, "duration", lambda study: calls.append(1) or duration(study))
    client = Client()
    client.get(f"/s/{on_prolific.slug}/", ids("d" * 24))
    calls.clear()
    assert client.post(f"/s/{on_prolific.slug}/consent/", {"agree": "1"}).status_code == 302
    assert Participant.objects.filter(study=on_prolific, consented_at__isnull=False).count() == 1
    assert len(calls) == 1


def test_minutes_kept_by_the_process_never_time_out_someone_the_study_would_not(on_prolific):
    import time

    client = Client()
    client.get(f"/s/{on_prolific.slug}/", ids("c" * 24))
    assert client.post(f"/s/{on_prolific.slug}/consent/", {"agree": "1"}).status_code == 302
    person = Participant.objects.get(study=on_prolific)
    # A page read the row as it stands (on SQLite the consent's lock moved its version).
    assert client.get(f"/s/{on_prolific.slug}/instructions/").status_code == 200
    # The process kept the study's minutes when a session was estimated at 1 minute
    # (Prolific's default limit: 5 minutes) ...
    kept = Study.objects.cached(on_prolific.slug)
    kept.__dict__["_worked_out"]["minutes"] = (kept.version, time.monotonic(), 1)
    assert kept.time_limit() == timedelta(minutes=5)
    # ... and 5 participants have since taken 20 minutes each: the study takes 20 (limit 60).
    now = timezone.now()
    for k in range(5):
        Participant.objects.create(study=on_prolific, seed=100 + k, consented_at=now,
                                   completed_at=now + timedelta(minutes=20),
                                   outcome=Participant.Outcome.COMPLETED)
    Participant.objects.filter(pk=person.pk).update(consented_at=now - timedelta(minutes=8))
    assert client.get(f"/s/{on_prolific.slug}/instructions/").status_code == 200
    person.refresh_from_db()
    assert person.outcome == ""
    # Past the study's own limit, the outcome is stored.
    Participant.objects.filter(pk=person.pk).update(consented_at=now - timedelta(minutes=61),
                                                    active_at=now)
    assert client.get(f"/s/{on_prolific.slug}/instructions/").status_code == 410
    person.refresh_from_db()
    assert person.outcome == Participant.Outcome.TIMED_OUT
