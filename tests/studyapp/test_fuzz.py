"""Bad input at the participant pages: tampered answers, foreign ids, huge bodies, script.

Every refusal is a 4xx with a message, stores nothing, and reflects nothing unescaped.
"""

import os

import pytest
from django.test import Client
from hypothesis import HealthCheck, example, given, settings, strategies as st


pytestmark = pytest.mark.django_db

SCRIPT = "<script>alert(1)</script>"
# STUDY_FUZZ_EXAMPLES=2000 for a longer campaign (docs/FAULTS.md).
FUZZ = settings(max_examples=int(os.environ.get("STUDY_FUZZ_EXAMPLES", "50")), deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture
def joined(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="fuzz")
    bot.trial_page()  # shown and its clips fetched: only the answer is left to check
    return bot


def stored_answers(study):
    from studyapp.survey.models import Trial

    return Trial.objects.filter(participant__study=study, answered_at__isnull=False).count()


def assert_refused(response, study):
    assert 400 <= response.status_code < 500, response.status_code
    assert SCRIPT.encode() not in response.content
    assert stored_answers(study) == 0


def tokens_of(bot, trial):
    return [item.token for item in trial.items.order_by("position")]


@FUZZ
@given(ranks=st.lists(st.one_of(st.integers(-10**12, 10**12), st.text(max_size=20)), min_size=3, max_size=3))
def test_tampered_ranks_are_refused_unless_a_permutation(joined, ranks):
    trial = joined.participant().current_trial()
    data = joined.answer_data(trial)
    for token, rank in zip(tokens_of(joined, trial), ranks):
        data[f"rank_{token}"] = str(rank)
    response = joined.answer(data)
    valid = sorted(str(r) for r in ranks) == ["1", "2", "3"]
    if valid:
        assert response.status_code == 302
        trial.refresh_from_db()
        assert trial.answered_at is not None
        trial.__class__.objects.filter(pk=trial.pk).update(answered_at=None)  # next example
        from studyapp.survey.models import Participant

        Participant.objects.filter(pk=trial.participant_id).update(completed_at=None, outcome="")
    else:
        assert_refused(response, joined.study)


@FUZZ
@given(
    drop=st.sets(st.integers(0, 2), max_size=3),
    foreign=st.lists(st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789_-", min_size=1, max_size=40), max_size=3),
    plays=st.one_of(st.integers(-5, 0), st.text(max_size=5).filter(lambda s: not s.strip().isdigit())),
)
def test_missing_foreign_and_unplayed_clips_are_refused(joined, drop, foreign, plays):
    trial = joined.participant().current_trial()
    tokens = tokens_of(joined, trial)
    data = joined.answer_data(trial)
    for k in drop:
        data.pop(f"rank_{tokens[k]}")
    for token in foreign:
        data[f"rank_{token}"] = "1"
    if not drop and not [t for t in foreign if t not in tokens]:
        data[f"plays_{tokens[0]}"] = str(plays)  # at least one thing is wrong
    response = joined.answer(data)
    if response.status_code == 302:  # an unknown extra field may be ignored; then all else was valid
        assert not drop
        return
    assert_refused(response, joined.study)


@FUZZ
@given(trial_id=st.one_of(st.integers(0, 10**30).map(str), st.text(max_size=30)))
@example(trial_id="9" * 25)  # beyond any integer column
@example(trial_id="\u00b2")  # a digit to str.isdigit, not to int()
def test_foreign_or_garbled_trial_ids_are_refused(joined, trial_id):
    own = set(joined.participant().trials.values_list("pk", flat=True))
    if trial_id.isascii() and trial_id.strip().isdigit() and int(trial_id) in own:
        return
    data = joined.answer_data(joined.participant().current_trial())
    data["trial"] = trial_id
    assert_refused(joined.answer(data), joined.study)


def test_another_participants_trial_is_refused(ranking_study, make_bot):
    alice, bob = make_bot(ranking_study), make_bot(ranking_study)
    alice.join(PROLIFIC_PID="alice")
    bob.join(PROLIFIC_PID="bob")
    data = alice.answer_data(alice.participant().current_trial())
    response = bob.answer(data)
    assert response.status_code == 400
    assert b"not part of your session" in response.content
    assert stored_answers(ranking_study) == 0


def test_oversized_body_is_refused(joined):
    data = joined.answer_data(joined.participant().current_trial())
    data["comments"] = "x" * (300 * 1024)
    response = joined.answer(data)
    assert response.status_code == 400
    assert stored_answers(joined.study) == 0


@FUZZ
@given(pid=st.text(min_size=1, max_size=300).map(lambda s: s + SCRIPT))
def test_script_in_crowd_ids_is_never_reflected(ranking_study, pid):
    from studyapp.survey.models import Participant

    client = Client()
    for response in (client.get(f"/s/{ranking_study.slug}/", {"PROLIFIC_PID": pid}, follow=True),
                     client.post(f"/s/{ranking_study.slug}/consent/", {"agree": "1"}, follow=True)):
        assert response.status_code < 500
        assert SCRIPT.encode() not in response.content
    stored = Participant.objects.filter(study=ranking_study).order_by("-pk").first()
    if stored is not None:
        assert len(stored.external_key) <= 200  # ids are cut to a bounded length


def test_script_in_free_text_is_escaped(ranking_study, make_bot):
    ranking_study.ask_demographics = True
    ranking_study.save()
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="free-text")
    bot.finish()
    response = bot.client.post(bot.url("about-you"), {"comments": SCRIPT, "age_range": SCRIPT,
                                                       "gender": SCRIPT}, follow=True)
    assert response.status_code in (200, 400)
    assert SCRIPT.encode() not in response.content


def test_every_participant_form_needs_the_csrf_token(ranking_study):
    client = Client(enforce_csrf_checks=True)
    client.get(f"/s/{ranking_study.slug}/", {"PROLIFIC_PID": "csrf"})
    for name in ("consent", "instructions", "trial", "about-you"):
        response = client.post(f"/s/{ranking_study.slug}/{name}/", {"agree": "1"})
        assert response.status_code == 403, name
    from studyapp.survey.models import Participant

    assert not Participant.objects.filter(study=ranking_study).exists()


def test_admin_needs_login_and_preview_needs_staff(ranking_study, client):
    for url in ("/admin/", "/admin/survey/study/", f"/preview/{ranking_study.slug}/"):
        response = client.get(url)
        assert response.status_code == 302 and "/admin/login/" in response["Location"], url


def test_stimulus_sources_and_media_are_not_readable(joined, ranking_study):
    page = joined.trial_page().content.decode()
    for source in ("real", "a2m", "cond_gru"):
        assert f">{source}<" not in page and f'"{source}"' not in page
    for path in ("/media/", "/media/stimuli/", "/c/../../settings.py", "/c/notatoken.mp4"):
        assert joined.client.get(path).status_code == 404, path


def test_entry_rate_limit_per_ip(ranking_study, settings):
    from django.core.cache import cache

    from studyapp.participation import ratelimit

    assert "studyapp.participation.ratelimit.EntryRateLimitMiddleware" in settings.MIDDLEWARE
    settings.STUDY_ENTRY_RATE_LIMIT = "5/h"  # fixed windows: an hour is never crossed here
    cache.clear()
    statuses = [Client().get(f"/s/{ranking_study.slug}/", {"PROLIFIC_PID": f"p{i}"}).status_code
                for i in range(8)]
    assert statuses == [302] * 5 + [429] * 3
    other = Client(REMOTE_ADDR="10.0.0.2").get(f"/s/{ranking_study.slug}/")
    assert other.status_code == 302  # another address has its own bucket
    assert ratelimit.allow("k", "1/s", now=100.0) and not ratelimit.allow("k", "1/s", now=100.1)
    assert ratelimit.allow("k", "1/s", now=101.2)
    with pytest.raises(ValueError):
        ratelimit.parse_rate("lots")
    cache.clear()


def test_the_rate_limit_fails_open_when_its_cache_is_down(ranking_study, settings, caplog):
    # A Redis outage must not stop the study: entries go through, and it is logged.
    settings.CACHES = {"default": {"BACKEND": "django.core.cache.backends.redis.RedisCache",
                                   "LOCATION": "redis://127.0.0.1:9/0"}}  # nothing listens
    settings.STUDY_ENTRY_RATE_LIMIT = "1/h"
    statuses = [Client().get(f"/s/{ranking_study.slug}/", {"PROLIFIC_PID": f"down{i}"}).status_code
                for i in range(3)]
    assert statuses == [302] * 3
    assert "rate limit not applied" in caplog.text


def test_a_refusal_says_how_long_to_wait(ranking_study, settings):
    from django.core.cache import cache

    from studyapp.participation import ratelimit

    settings.STUDY_ENTRY_RATE_LIMIT = "1/h"
    cache.clear()
    client = Client()
    assert client.get(f"/s/{ranking_study.slug}/", {"PROLIFIC_PID": "w1"}).status_code == 302
    refused = client.get(f"/s/{ranking_study.slug}/", {"PROLIFIC_PID": "w2"})
    assert refused.status_code == 429 and 1 <= int(refused["Retry-After"]) <= 3600
    assert ratelimit.retry_after("1/h", now=7200.0 + 600) == 3000
    assert ratelimit.retry_after("120/min", now=59.5) == 1
    cache.clear()


def test_long_crowd_ids_still_fit_in_the_cookie(ranking_study):
    from studyapp.participation.flow import cookie_name
    from studyapp.survey.models import Participant

    ids = {name: "\u00e9\u4e2d" * 60 for name in ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID",
                                                 "assignmentId", "hitId")}
    client = Client()
    client.get(f"/s/{ranking_study.slug}/", ids)
    assert len(client.cookies[cookie_name(ranking_study)].value) < 4000
    assert client.post(f"/s/{ranking_study.slug}/consent/", {"agree": "1"}).status_code == 302
    stored = Participant.objects.get(study=ranking_study)
    assert stored.external_ids["PROLIFIC_PID"].startswith("\u00e9\u4e2d")
