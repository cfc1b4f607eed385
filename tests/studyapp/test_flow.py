"""The ranking study through Django's test client: flow, assignment, answers, clips."""

import re
from collections import Counter
from datetime import timedelta
from pathlib import Path

import pytest
from django.conf import settings
from django.contrib.staticfiles import finders
from django.utils import timezone

from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem
from studyapp.stimuli.clips import Clip, register_clips
from studyapp.survey.study_types import list_study_types
from tests.studyapp.conftest import SOURCES, make_stimuli, words

pytestmark = pytest.mark.django_db


# Registering clips


def test_register_clips_copies_each_video_once(ranking_study, clips, media_root):
    stimuli = list(ranking_study.stimuli.all())
    assert len(stimuli) == 6
    for stimulus in stimuli:
        assert re.fullmatch(r"stimuli/[0-9a-f]{64}\.mp4", stimulus.video)
        assert (Path(media_root) / stimulus.video).read_bytes()[4:8] == b"ftyp"
        assert (Path(media_root) / stimulus.poster).is_file()
    again = register_clips(ranking_study, clips)
    assert sorted(s.pk for s in again) == sorted(s.pk for s in stimuli)
    assert len(list((Path(media_root) / "stimuli").iterdir())) == 12


def test_a_rebuild_registers_a_clip_s_new_payload(ranking_study, clips, media_root, tmp_path):
    """A payload made anew (another payload version, names are content hashes) replaces
    the one a stimulus had, so rebuilding the stimuli brings old payloads up to date."""
    old, new = tmp_path / "0123456789abcdef.motion", tmp_path / "fedcba9876543210.motion"
    old.write_bytes(b"old payload")
    new.write_bytes(b"new payload")
    clip = clips[0]
    register_clips(ranking_study, [Clip(**{**clip.__dict__, "motion": old})])
    stimulus = register_clips(ranking_study, [Clip(**{**clip.__dict__, "motion": new})])[0]
    stimulus.refresh_from_db()
    assert stimulus.motion == f"stimuli/{new.name}"
    assert (Path(media_root) / stimulus.motion).read_bytes() == b"new payload"


def test_register_clips_refuses_a_video_under_another_source(ranking_study, clips):
    clip = clips[0]
    moved = Clip(clip.action, "other", clip.video, 0.4)
    with pytest.raises(ValueError, match="already in study"):
        register_clips(ranking_study, [moved])


def test_create_study_fills_in_texts():
    study = Study.objects.create_study("ranking", "plain", "Plain", clips_per_trial=6)
    assert study.study_type == "ranking"
    assert "rank 6" in study.instructions
    # The consent is the type's default, saying the study's own minutes when shown.
    assert not study.consent_text and "It takes about 1 minute." in study.shown_consent()


@pytest.mark.parametrize("name", list_study_types())
def test_every_study_type_runs_through_the_shared_flow(name, media_root, clips, make_bot):
    """Contract: defaults, balanced trials, a trial page with the gate, a strict form."""
    study = Study.objects.create_study(name, f"type-{name.replace('_', '-')}", "Contract")
    assert study.shown_instructions() and study.shown_consent()
    register_clips(study, clips)
    bot = make_bot(study)
    bot.join()
    trials = list(bot.participant().trials.all())
    assert trials and all(trial.items.count() >= study.kind.min_items for trial in trials)
    page = bot.trial_page().content.decode()
    assert "data-trial-form" in page and "data-submit" in page and "disabled" in page
    for item in trials[0].items.all():
        assert f"/c/{item.token}.mp4" in page and item.stimulus.token not in page
    assert bot.answer({"trial": str(trials[0].pk)}).status_code == 400


# Entering and consenting


def test_consent_is_required(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    response = bot.enter()
    assert response.redirect_chain[-1][0].endswith("/consent/")
    assert ranking_study.data_note.encode() in response.content
    response = bot.consent(agree=False)
    assert b"Please tick the box" in response.content
    assert not Participant.objects.exists()
    bot.client.post(bot.url("instructions"))
    assert not Participant.objects.exists()
    response = bot.consent()
    assert response.redirect_chain[-1][0].endswith("/instructions/")
    assert Participant.objects.get().consented_at is not None


@pytest.mark.parametrize(
    "params, key",
    [
        ({"PROLIFIC_PID": "p1", "STUDY_ID": "s1", "SESSION_ID": "x1"}, "PROLIFIC_PID:p1"),
        ({"participant_label": "w1"}, "participant_label:w1"),
    ],
)
def test_platform_ids_are_stored(ranking_study, make_bot, params, key):
    bot = make_bot(ranking_study)
    bot.enter(**params, other="ignored")
    bot.consent()
    participant = Participant.objects.get()
    assert participant.external_ids == params
    assert participant.external_key == key
    assert participant.seed > 0


def test_a_person_cannot_take_a_study_twice(ranking_study, make_bot):
    first = make_bot(ranking_study)
    first.join(PROLIFIC_PID="same")
    elsewhere = make_bot(ranking_study)
    elsewhere.enter(PROLIFIC_PID="same")
    assert elsewhere.participant() == first.participant()  # still in progress: resumes
    first.finish()
    again = make_bot(ranking_study)
    response = again.enter(PROLIFIC_PID="same")  # finished: shown their code again
    assert response.redirect_chain[-1][0].endswith("/done/")
    assert first.participant().completion_code.encode() in response.content
    again.consent()
    assert Participant.objects.count() == 1


def test_closed_or_full_study_says_so(ranking_study, make_bot):
    make_bot(ranking_study).join()
    Study.objects.filter(pk=ranking_study.pk).update(max_participants=1)
    assert b"This study is full" in make_bot(ranking_study).enter().content
    Study.objects.filter(pk=ranking_study.pk).update(status="closed", max_participants=None)
    assert b"This study is not open" in make_bot(ranking_study).enter().content
    assert Participant.objects.count() == 1


def test_a_kept_study_row_is_read_again_once_any_update_changes_it(ranking_study, make_bot):
    """Each process keeps study rows (``Study.objects.cached``); every UPDATE of the row,
    a queryset's as much as a save, moves ``version`` on (a database trigger), and the
    participant's page, whose one statement reads the version too, reads the row again."""
    bot = make_bot(ranking_study)
    bot.join()
    version = Study.objects.get(pk=ranking_study.pk).version
    Study.objects.filter(pk=ranking_study.pk).update(title="A new title")
    assert Study.objects.get(pk=ranking_study.pk).version == version + 1
    kept = Study.objects.cached(ranking_study.slug)
    assert kept.title != "A new title" or kept.version == version + 1
    assert b"A new title" in bot.trial_page(watch=False).content
    assert Study.objects.cached(ranking_study.slug).title == "A new title"
    study = Study.objects.get(pk=ranking_study.pk)
    study.title = "Saved"
    study.save()
    assert Study.objects.get(pk=ranking_study.pk).version == version + 2
    assert b"Saved" in bot.trial_page(watch=False).content
    # A save of a row read before another update still moves the version on, never back
    # to one a process may keep.
    Study.objects.filter(pk=ranking_study.pk).update(title="Elsewhere")
    study.title = "Stale save"
    study.save()
    assert Study.objects.get(pk=ranking_study.pk).version > version + 3
    assert b"Stale save" in bot.trial_page(watch=False).content
    # A page with no participant yet checks the version on its own.
    Study.objects.filter(pk=ranking_study.pk).update(status="closed")
    assert b"This study is not open" in make_bot(ranking_study).enter().content
    assert Study.objects.cached(ranking_study.slug).status == "closed"


# Assignment


def test_assignment_is_balanced_over_stimuli_and_positions(media_root, make_bot):
    study = Study.objects.create_study("ranking", "balanced", "Balanced", clips_per_trial=3)
    make_stimuli(study, per_cell=3)
    for _ in range(7):
        make_bot(study).join()
    counts = Counter({s.pk: 0 for s in study.stimuli.all()})
    counts.update(TrialItem.objects.values_list("stimulus", flat=True))
    assert max(counts.values()) - min(counts.values()) <= 1
    for trial in Trial.objects.all():
        assert sorted(trial.items.values_list("stimulus__source", flat=True)) == sorted(SOURCES)
        assert {trial.action} == set(trial.items.values_list("stimulus__action", flat=True))
    seats = Counter(TrialItem.objects.values_list("stimulus__source", "position"))
    assert len(seats) == 9  # every source has been at every position
    assert max(seats.values()) - min(seats.values()) <= 2
    assert Trial.objects.count() == 14


def test_each_participant_gets_their_own_order(media_root, make_bot):
    study = Study.objects.create_study("ranking", "orders", "Orders", clips_per_trial=3)
    make_stimuli(study)
    orders = set()
    for _ in range(6):
        bot = make_bot(study)
        bot.join()
        participant = bot.participant()
        orders.add(
            tuple(
                tuple(trial.items.values_list("stimulus__source", flat=True))
                for trial in participant.trials.all()
            )
        )
    assert len(orders) > 1


# Answers


def test_an_answer_gets_the_next_trial_in_its_response(ranking_study, make_bot):
    """One request per answer: the trial form's ``next`` field makes the answer's response
    the next trial page (marked shown); after the last trial, and for a repeated submit,
    the answer redirects as a form without the field does."""
    bot = make_bot(ranking_study)
    bot.join()
    first = bot.participant().current_trial()
    page = bot.trial_page()
    assert b'name="next" value="trial"' in page.content
    response = bot.answer(bot.answer_data(first) | {"next": "trial"})
    assert response.status_code == 200
    second = bot.participant().current_trial()
    assert second.index == first.index + 1 and second.shown_at is not None
    assert f'name="trial" value="{second.pk}"'.encode() in response.content
    first.refresh_from_db()
    assert first.answered_at is not None
    again = bot.answer(bot.answer_data(first) | {"next": "trial"})
    assert again.status_code == 302 and again["Location"].endswith("/trial/")
    last = bot.participant().trials.count() - 1
    while (trial := bot.participant().current_trial()) is not None:
        bot.watch(trial)
        response = bot.answer(bot.answer_data(trial) | {"next": "trial"})
        assert response.status_code == (302 if trial.index == last else 200)
    assert response["Location"].endswith(("/about-you/", "/done/"))
    assert bot.participant().completed_at is not None


def test_a_valid_ranking_is_stored(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    page = bot.trial_page()
    assert page.status_code == 200
    Trial.objects.filter(pk=trial.pk).update(shown_at=timezone.now() - timedelta(seconds=2))
    data = bot.answer_data(trial, ranks={0: 2, 1: 3, 2: 1}, plays=2)
    response = bot.answer(data)
    assert response.status_code == 302
    trial.refresh_from_db()
    assert trial.answered_at is not None and 2000 <= trial.time_ms < 10_000
    stored = list(trial.items.order_by("position").values_list("position", "answers", "plays"))
    assert stored == [(0, {"preference": 2}, 2), (1, {"preference": 3}, 2),
                      (2, {"preference": 1}, 2)]


def other_participants_trial(study, make_bot):
    other = make_bot(study)
    other.join()
    return other.participant().current_trial()


TAMPERINGS = {
    "duplicate rank": lambda d, t: d | {key(d, "rank", 0): d[key(d, "rank", 1)]},
    "rank out of range": lambda d, t: d | {key(d, "rank", 0): "4"},
    "rank zero": lambda d, t: d | {key(d, "rank", 0): "0"},
    "non-numeric rank": lambda d, t: d | {key(d, "rank", 0): "first"},
    "non-numeric plays": lambda d, t: d | {key(d, "plays", 0): "many"},
    "plays zero": lambda d, t: d | {key(d, "plays", 2): "0"},
    "missing item": lambda d, t: {k: v for k, v in d.items() if not k.endswith(token(d, 1))},
    "foreign stimulus": lambda d, t: d | {f"{p}_{t['foreign']}": "1" for p in ("rank", "plays")},
    "another participant's trial": lambda d, t: d | {"trial": str(t["other"].pk)},
    "no trial": lambda d, t: {k: v for k, v in d.items() if k != "trial"},
    "non-numeric trial": lambda d, t: d | {"trial": "1; DROP TABLE"},
}


def token(data, index):
    return sorted(k for k in data if k.startswith("rank_"))[index].removeprefix("rank_")


def key(data, prefix, index):
    return f"{prefix}_{token(data, index)}"


@pytest.mark.parametrize("tampering", sorted(TAMPERINGS))
def test_a_tampered_answer_is_refused_and_nothing_stored(ranking_study, make_bot, tampering):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    other = other_participants_trial(ranking_study, make_bot)
    extra = {"foreign": other.items.first().token, "other": other}
    response = bot.answer(TAMPERINGS[tampering](bot.answer_data(trial), extra))
    assert response.status_code == 400
    assert b"Your answer was not saved" in response.content
    assert not TrialItem.objects.exclude(answers={}).exists()
    assert not TrialItem.objects.exclude(plays=0).exists()
    assert not Trial.objects.filter(answered_at__isnull=False).exists()


def test_the_refusal_says_what_is_wrong(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    data = bot.answer_data(trial, ranks={0: 1, 1: 1, 2: 3})
    assert b"Rank 1 is given to more than one clip" in bot.answer(data).content
    data = bot.answer_data(trial, plays=0)
    assert b"has not been played to the end yet" in bot.answer(data).content


def test_a_second_submit_stores_nothing_new(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    first = bot.answer_data(trial, ranks={0: 1, 1: 2, 2: 3})
    assert bot.answer(first).status_code == 302
    answered_at = Trial.objects.get(pk=trial.pk).answered_at
    second = bot.answer(bot.answer_data(trial, ranks={0: 3, 1: 2, 2: 1}, plays=5))
    assert second.status_code == 302 and second.url.endswith("/trial/")
    assert Trial.objects.get(pk=trial.pk).answered_at == answered_at
    assert list(trial.items.order_by("position").values_list("answers", "plays")) == [
        ({"preference": 1}, 1),
        ({"preference": 2}, 1),
        ({"preference": 3}, 1),
    ]


def test_a_reload_resumes_at_the_same_trial(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join()
    first = bot.participant().current_trial()
    assert f'name="trial" value="{first.pk}"'.encode() in bot.trial_page().content
    response = bot.enter()
    assert response.redirect_chain[-1][0].endswith("/trial/")
    assert f'value="{first.pk}"'.encode() in response.content
    shown_at = Trial.objects.get(pk=first.pk).shown_at
    bot.client.get(bot.url("consent"), follow=True)
    assert Trial.objects.get(pk=first.pk).shown_at == shown_at
    bot.answer(bot.answer_data(first))
    second = bot.participant().current_trial()
    assert second.index == 1
    assert f'value="{second.pk}"'.encode() in bot.enter().content


def test_completion_shows_the_code_and_the_way_back(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="done1")
    response = bot.finish()
    participant = bot.participant()
    assert participant.completed_at is not None
    assert re.fullmatch(r"[0-9A-F]{8}", participant.completion_code)
    assert participant.completion_code.encode() in response.content
    assert b'href="https://platform.example/complete?cc=OK"' in response.content
    assert bot.enter().redirect_chain[-1][0].endswith("/done/")
    assert bot.answer({"trial": "1"}).status_code == 302


# Clips


def test_clips_are_served_in_byte_ranges(ranking_study, client, media_root, make_bot):
    bot = make_bot(ranking_study)
    bot.join()
    item = bot.participant().current_trial().items.select_related("stimulus").first()
    stimulus = item.stimulus
    url = f"/c/{item.token}.mp4"
    data = (Path(media_root) / stimulus.video).read_bytes()
    full = client.get(url)
    assert full.status_code == 200 and b"".join(full.streaming_content) == data
    assert full["Accept-Ranges"] == "bytes" and full["Content-Type"] == "video/mp4"
    part = client.get(url, HTTP_RANGE="bytes=10-109")
    assert part.status_code == 206
    assert part["Content-Range"] == f"bytes 10-109/{len(data)}"
    assert part["Content-Length"] == "100"
    assert b"".join(part.streaming_content) == data[10:110]
    tail = client.get(url, HTTP_RANGE="bytes=-16")
    assert b"".join(tail.streaming_content) == data[-16:]
    assert client.get(url, HTTP_RANGE=f"bytes={len(data)}-").status_code == 416
    assert client.get(url, HTTP_IF_NONE_MATCH=full["ETag"]).status_code == 304
    assert client.head(url)["Content-Length"] == str(len(data))
    for header in ("Content-Disposition", "Last-Modified"):
        assert header not in full
    assert client.get(f"/c/{item.token}.png")["Content-Type"] == "image/png"
    assert client.get("/c/AAAAAAAAAAAAAAAAAAAAAA.mp4").status_code == 404
    assert client.get(f"/c/{stimulus.token}.mp4").status_code == 404  # not a participant's
    assert client.get(f"/p/{stimulus.token}.mp4").status_code == 302  # staff only: log in


# Blindness


def test_nothing_a_participant_receives_names_a_source(ranking_study, make_bot):
    """Fetch every page, script, style sheet and clip of a session; search for sources."""
    bot = make_bot(ranking_study)
    responses = [bot.enter(PROLIFIC_PID="blind"), bot.consent(), bot.start()]
    while (trial := bot.participant().current_trial()) is not None:
        responses.append(bot.trial_page())
        responses.append(bot.answer(bot.answer_data(trial, plays=0)))  # the 400 page
        responses.append(bot.answer(bot.answer_data(trial), follow=True))
    texts = []
    for response in responses:
        html = response.content.decode()
        texts.append(html.replace(ranking_study.data_note, ""))
        texts.append(str(dict(response.items())))
        for url in re.findall(r'(?:src|href|poster)="([^"]+)"', html):
            if url.startswith(settings.STATIC_URL) or url.startswith("/" + settings.STATIC_URL):
                texts.append(Path(finders.find(url.split(settings.STATIC_URL, 1)[1])).read_text())
            elif url.startswith("/c/"):
                clip = bot.client.get(url, HTTP_RANGE="bytes=0-")
                texts.append(str(dict(clip.items())))
                texts.append(b"".join(clip.streaming_content).decode("latin-1"))
    assert any("/c/" in text for text in texts) and any("drag" in text for text in texts)
    labels = set(Stimulus.objects.values_list("source", flat=True))
    labels |= {"generated", "fake", "condgru"}
    for label in labels:
        for text in texts:
            assert not words(text, label), f"{label!r} leaks: {words(text, label)[:3]}"


# Admin


def test_admin_lists_studies_stimuli_participants_trials_responses(
    ranking_study, make_bot, admin_client
):
    for _ in range(3):
        make_bot(ranking_study).join()
    bot = make_bot(ranking_study)
    bot.join()
    bot.finish()
    studies = admin_client.get("/admin/survey/study/")
    assert studies.status_code == 200
    row = re.search(rb'<tr>.*?motion-study.*?</tr>', studies.content, re.S).group(0)
    assert re.findall(rb'class="field-(?:started|completed|judgements)">(\d+)<', row) == [
        b"4",
        b"1",
        b"6",
    ]
    assert b'href="/s/motion-study/"' in row
    for path in (
        "/admin/survey/stimulus/?source=a2m",
        "/admin/survey/participant/",
        "/admin/survey/trial/",
        "/admin/survey/response/?stimulus__source=real",
        f"/admin/survey/trial/{Trial.objects.first().pk}/change/",
        f"/admin/survey/participant/{Participant.objects.first().pk}/change/",
        f"/admin/survey/stimulus/{Stimulus.objects.first().pk}/change/",
    ):
        assert admin_client.get(path).status_code == 200, path
    assert b"<video" in admin_client.get("/admin/survey/stimulus/").content


def test_by_token_counts_trials_and_finds_the_current_one(ranking_study, make_bot):
    from studyapp.survey.models import Participant, Trial

    bot = make_bot(ranking_study)
    bot.enter(PROLIFIC_PID="progress")
    bot.consent()
    row = bot.participant()
    before = Participant.objects.by_token(ranking_study, row.token)
    assert (before.pk, before.n_trials, before.n_practice, before.current_id) == (row.pk, 0, 0, None)
    assert not before.has_trials()
    bot.start()
    trials = list(row.trials.order_by("index"))
    for answered in range(len(trials) + 1):
        read = Participant.objects.by_token(ranking_study, row.token)
        assert read.n_trials == len(trials)
        assert read.n_practice == sum(t.kind == Trial.Kind.PRACTICE for t in trials)
        assert read.current_id == (trials[answered].pk if answered < len(trials) else None)
        if answered < len(trials):
            bot.trial_page()
            assert bot.answer(bot.answer_data(trials[answered])).status_code == 302
    assert Participant.objects.by_token(ranking_study, "no-such-token") is None
    assert read.completed_at is not None and read.external_ids == {"PROLIFIC_PID": "progress"}


# A Prolific study whose time limit is the platform's default: it comes from the study's
# minutes, which plan a session and read every completion (the kept row keeps them).
PROLIFIC_DEFAULT_LIMIT = {"platform": "prolific", "codes": {"completed": "C1", "no_consent": "N1"}}


@pytest.mark.parametrize("crowd", [None, PROLIFIC_DEFAULT_LIMIT], ids=["no platform", "prolific"])
def test_an_answer_and_the_next_trial_cost_six_statements(db, media_root, clips, make_bot, crowd):
    from django.db import connection
    from django.test.utils import CaptureQueriesContext

    # The participant with progress and the study's version (the study row is kept by
    # the process; no session: the participant is in a signed cookie), the trial with
    # items and the next one with its items (one statement); the answer's conditional
    # UPDATE, the items' UPDATE (one statement per item, sent as one executemany) and the
    # participant's active_at (the next trial was read: not the last answer); the next
    # trial's shown_at (docs/BENCHMARKS.md, "Load"): one request. Without the form's
    # ``next`` field, the redirect's GET reads the participant again. Transaction control
    # is not counted.
    def statements(captured):
        return [q["sql"] for q in captured.captured_queries
                if not q["sql"].startswith(("SAVEPOINT", "RELEASE SAVEPOINT"))]

    from tests.studyapp.conftest import make_ranking_study

    ranking_study = make_ranking_study(clips, trials_per_participant=3,
                                       **({"crowd": crowd} if crowd else {}))
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="5f3a9c2e1b4d6a7f8e9c0b1a", STUDY_ID="60aaca280709ee40ec37d488",
             SESSION_ID="6" * 24)
    Study.objects.cached(ranking_study.slug)  # as a process that served a page before
    trial = bot.participant().current_trial()
    bot.trial_page()
    data = bot.answer_data(trial) | {"next": "trial"}
    with CaptureQueriesContext(connection) as captured:
        assert bot.answer(data).status_code == 200
    assert len(statements(captured)) == 6, "\n".join(statements(captured))
    trial = bot.participant().current_trial()
    bot.watch(trial)
    data = bot.answer_data(trial)
    with CaptureQueriesContext(connection) as captured:
        assert bot.answer(data).status_code == 302
        assert bot.trial_page(watch=False).status_code == 200
    assert len(statements(captured)) == 8, "\n".join(statements(captured))
    assert not any("django_session" in sql for sql in statements(captured))


def test_the_participant_cookie_is_signed_and_no_session_is_made(ranking_study, make_bot):
    from django.core import signing

    from studyapp.participation.flow import COOKIE_SALT, cookie_name

    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="signed")
    token = bot.participant().token
    assert bot.trial_page().status_code == 200
    assert "sessionid" not in bot.client.cookies  # nothing server-side per participant
    name = cookie_name(ranking_study)
    value = bot.client.cookies[name].value
    assert signing.loads(value, salt=COOKIE_SALT) == {"p": token}
    for forged in (value[:-2] + ("AA" if not value.endswith("AA") else "BB"),
                   signing.dumps({"p": token}, salt="another-salt"), "garbage", ""):
        stranger = make_bot(ranking_study)
        stranger.client.cookies[name] = forged
        response = stranger.client.get(stranger.url("trial"))
        assert response.status_code == 302 and response["Location"].endswith("/consent/")


def test_a_trial_without_clips_shows_an_error_page_not_a_redirect_loop(ranking_study, make_bot):
    from studyapp.survey.models import TrialItem

    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="broken")
    TrialItem.objects.filter(trial=bot.participant().current_trial()).delete()  # broken data
    response = bot.trial_page()
    assert response.status_code == 500
    assert b"Something is wrong with this study" in response.content


def test_a_start_inserts_trials_and_items_in_three_statements_and_counts_them(db, media_root, clips):
    from django.db import connection
    from django.test.utils import CaptureQueriesContext

    from tests.studyapp.conftest import make_ranking_study

    # With the study's row locked, whatever the number of trials: the trials, the
    # repeats (they point at their originals) and every item (docs/BENCHMARKS.md, "Load").
    study = make_ranking_study(clips, trials_per_participant=3, repeat_trials=1)
    participant = Participant.objects.enroll(study, {}, "starting")
    with CaptureQueriesContext(connection) as captured:
        Participant.objects.start(participant)
    inserts = [q["sql"] for q in captured.captured_queries
               if q["sql"].startswith(("INSERT INTO \"survey_trial\"",
                                       "INSERT INTO \"survey_trialitem\""))]
    assert len(inserts) == 3, inserts
    # Then the balance counts: one upsert and the row of what is counted (created by the
    # first start, updated by the later ones); a start costs the same however many before.
    kept = [q["sql"] for q in captured.captured_queries if "survey_balance" in q["sql"]]
    assert len(kept) == 3, kept  # read the row (none yet), create it, upsert the counts
    statements = []
    for key in ("second", "third"):
        later = Participant.objects.enroll(study, {}, key)
        with CaptureQueriesContext(connection) as captured:
            Participant.objects.start(later)
        statements.append(len(captured))
    assert statements[0] == statements[1], statements
    trials = list(participant.trials.order_by("index"))
    repeat = next(trial for trial in trials if trial.kind == Trial.Kind.REPEAT)
    original = repeat.repeat_of
    assert original.participant_id == participant.pk and original.kind == Trial.Kind.MAIN
    # The repeat shows its original's clips, mirrored.
    assert ([item.stimulus_id for item in repeat.items.order_by("position")]
            == [item.stimulus_id for item in original.items.order_by("position")][::-1])
    assert all(trial.items.count() == 3 for trial in trials)
