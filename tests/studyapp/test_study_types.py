"""Every study type through Django's test client: answers, practice, catch and repeated
trials, balance (also under concurrent participants), blindness, demographics."""

import itertools
import re
import threading
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import pytest
from django.conf import settings
from django.contrib.staticfiles import finders
from django.db import connection
from django.test import Client

from studyapp.results.export import participants_frame, responses_frame
from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem
from studyapp.survey.study_types import get_study_type, list_study_types
from tests.studyapp.conftest import SOURCES, Bot, make_stimuli, make_study, words

pytestmark = pytest.mark.django_db

TYPES = list_study_types()
@pytest.fixture
def study_of(media_root, clips, extra_clips):
    return lambda study_type, **fields: make_study(study_type, clips, extra_clips, **fields)


def spread(study) -> int:
    """Return the largest difference in judgements between stimuli balance allows.

    A trial showing every source (or one clip) can take the least-used stimulus of
    each; a pair from three sources cannot when one source holds the two least used.
    """
    n = study.kind.items_per_trial(study)
    return 1 if n in (1, len(SOURCES)) else 2


def join(make_bot, study, **params):
    bot = make_bot(study)
    bot.join(**params)
    return bot


# Answers of every type


@pytest.mark.parametrize(
    "study_type, answers, stored",
    [
        ("fake_or_real", {"verdicts": {0: "generated"}}, {"items": [False]}),
        ("rating_standards", {"ratings": {0: 5, 1: 1, 2: 4}}, {"items": [5, 1, 4]}),
        ("rating_reference", {"ratings": {0: 2, 1: 3, 2: 2}}, {"items": [2, 3, 2]}),
        ("pairwise", {"choice": "right"}, {"trial": "right"}),
        ("pairwise_graded", {"choice": "right_slightly"}, {"trial": "right_slightly"}),
        ("best_of_k", {"pick": 2}, {"trial": 2}),
        ("best_of_k", {"pick": "all_bad"}, {"trial": "all_bad"}),
        ("mushra", {"scores": {0: 100, 1: 0, 2: 55}}, {"items": [100, 0, 55, 50, 50]}),
    ],
)
def test_an_answer_is_stored_under_the_first_criterion(
    study_of, make_bot, study_type, answers, stored
):
    study = study_of(study_type)
    bot = join(make_bot, study)
    trial = bot.participant().current_trial()
    bot.trial_page()
    assert bot.answer(bot.answer_data(trial, plays=2, **answers)).status_code == 302
    trial.refresh_from_db()
    items = list(trial.items.order_by("position"))
    assert trial.answered_at is not None and trial.time_ms is not None
    assert all(item.plays == 2 for item in items) and trial.kind == "main"
    key = study.kind.criteria(study)[0].key
    judged = [item for item in items if item.role == "judged"]
    got = {"items": [item.answers.get(key) for item in judged], "trial": trial.answers.get(key)}
    for name, value in stored.items():
        assert got[name] == value
    assert all(not item.answers for item in items if item.role != "judged")


@pytest.mark.parametrize(
    "study_type, tampering",
    [
        ("fake_or_real", lambda d: d | {k: "maybe" for k in d if k.startswith("judged_")}),
        ("rating_standards", lambda d: d | {next(k for k in d if k.startswith("rating_")): "6"}),
        ("rating_reference", lambda d: d | {next(k for k in d if k.startswith("rating_")): "0"}),
        ("pairwise", lambda d: d | {"choice": "both_good"}),  # ties not offered
        ("pairwise", lambda d: {k: v for k, v in d.items() if k != "choice"}),
        ("pairwise_graded", lambda d: d | {"choice": "both_good"}),  # not on its scale
        ("best_of_k", lambda d: d | {"pick": "none_good"}),  # not a clip nor an answer offered
        ("best_of_k", lambda d: {k: v for k, v in d.items() if k != "pick"}),
        ("mushra", lambda d: d | {next(k for k in d if k.startswith("score_")): "101"}),
        ("mushra", lambda d: {k: v for k, v in d.items() if k != next(
            n for n in d if n.startswith("score_"))}),  # a slider never moved
    ],
)
def test_a_tampered_answer_of_any_type_is_refused(study_of, make_bot, study_type, tampering):
    bot = join(make_bot, study_of(study_type))
    trial = bot.participant().current_trial()
    response = bot.answer(tampering(bot.answer_data(trial)))
    assert response.status_code == 400
    assert not Trial.objects.filter(answered_at__isnull=False).exists()


@pytest.mark.parametrize("study_type", TYPES)
def test_an_answer_before_every_clip_played_is_refused(study_of, make_bot, study_type):
    bot = join(make_bot, study_of(study_type))
    trial = bot.participant().current_trial()
    data = bot.answer_data(trial)
    data[next(k for k in data if k.startswith("plays_"))] = "0"
    response = bot.answer(data)
    assert response.status_code == 400
    assert b"has not been played to the end yet" in response.content
    assert not TrialItem.objects.exclude(plays=0).exists()


def test_pairwise_ties_are_offered_only_when_the_study_allows_them(study_of, make_bot):
    study = study_of("pairwise", allow_ties=True)
    assert "equally good" in study.instructions
    bot = join(make_bot, study)
    page = bot.trial_page().content.decode()
    assert 'value="both_good"' in page and 'value="both_bad"' in page
    trial = bot.participant().current_trial()
    assert bot.answer(bot.answer_data(trial, choice="both_bad")).status_code == 302
    assert Trial.objects.get(pk=trial.pk).answers == {"preference": "both_bad"}
    plain = study_of("pairwise", slug="no-ties")
    assert "equally" not in join(make_bot, plain).trial_page().content.decode()


# Practice, demographics, completion


@pytest.mark.parametrize("study_type", TYPES)
def test_the_practice_trial_comes_first_and_is_no_judgement(study_of, make_bot, study_type):
    study = study_of(study_type, practice=True, ask_demographics=True)
    bot = join(make_bot, study, PROLIFIC_PID="p1")
    trials = list(bot.participant().trials.order_by("index"))
    assert [t.kind for t in trials] == ["practice"] + ["main"] * (len(trials) - 1)
    page = bot.trial_page().content.decode()
    assert "Practice question" in page and "not counted" in page
    bot.answer(bot.answer_data(trials[0], ranks={0: 2, 1: 1, 2: 3}, ratings={0: 5}))
    practice = Trial.objects.get(pk=trials[0].pk)
    assert practice.answered_at is not None and practice.answers == {}
    assert not practice.items.exclude(answers={}).exists()
    practice_only = set(study.stimuli.filter(role="practice").values_list("pk", flat=True))
    assert set(practice.items.judged().values_list("stimulus", flat=True)) <= practice_only
    later = TrialItem.objects.filter(trial__in=trials[1:], stimulus__in=practice_only)
    assert not later.exists()  # practice clips are never judged
    page = bot.trial_page().content.decode()
    assert f"Question 1 of {len(trials) - 1}" in page and "practice is over" in page
    response = bot.finish()
    assert response.redirect_chain[-1][0].endswith("/about-you/")
    judgements = sum(t.items.judged().count() for t in trials[1:])
    assert Study.objects.with_counts().get().n_judgements == judgements
    table = responses_frame(study)
    assert len(table) == judgements and set(table["trial_kind"]) == {"main"}
    people = participants_frame(study)
    assert people["n_judgements"].tolist() == [judgements]
    assert people["PROLIFIC_PID"].tolist() == ["p1"]


def test_demographics_are_optional_and_stored_once(study_of, make_bot):
    study = study_of("pairwise", ask_demographics=True, completion_url="https://x.example/done")
    bot = join(make_bot, study)
    assert bot.finish().redirect_chain[-1][0].endswith("/about-you/")
    participant = bot.participant()
    assert participant.completed_at is not None and participant.demographics is None
    assert bot.enter().redirect_chain[-1][0].endswith("/about-you/")  # resumes there
    bad = bot.client.post(bot.url("about-you"), {"age_range": "12-17"})
    assert bad.status_code == 400
    answers = {"age_range": "25-34", "gender": "", "comments": "Clip B stuttered."}
    done = bot.client.post(bot.url("about-you"), answers, follow=True)
    assert participant.completion_code.encode() in done.content
    assert b"https://x.example/done" in done.content
    participant.refresh_from_db()
    assert participant.demographics == answers
    bot.client.post(bot.url("about-you"), {"age_range": "65+"})
    participant.refresh_from_db()
    assert participant.demographics == answers


# Catch and repeated trials


@pytest.mark.parametrize("study_type", TYPES)
@pytest.mark.parametrize("spotted", [True, False])
def test_a_catch_trial_is_graded(study_of, make_bot, study_type, spotted):
    study = study_of(study_type, catch=True, max_failed_catch=0)  # one failure fails
    bot = join(make_bot, study)
    trials = list(bot.participant().trials.order_by("index"))
    catch = [t for t in trials if t.kind == "catch"]
    assert len(catch) == 1 and trials[0].kind == "main"
    broken = catch[0].items.get(stimulus__role="catch")
    assert TrialItem.objects.filter(stimulus__role="catch").count() == 1
    good, bad = get_study_type(study_type).catch_answers(broken.position)
    while (trial := bot.participant().current_trial()) is not None:
        answers = (good if spotted else bad) if trial.kind == "catch" else {}
        bot.trial_page()
        assert bot.answer(bot.answer_data(trial, **answers)).status_code == 302
    assert Trial.objects.get(pk=catch[0].pk).catch_passed is spotted
    assert Study.objects.with_counts().get().n_excluded == (0 if spotted else 1)
    assert bot.participant().excluded() is not spotted


def test_catch_clips_never_enter_main_trials(study_of, make_bot):
    study = study_of("ranking", catch=True, catch_trials=0)
    for _ in range(3):
        join(make_bot, study)
    assert not TrialItem.objects.filter(stimulus__role="catch").exists()


@pytest.mark.parametrize(
    "study_type, same, different",
    [
        ("ranking", {"ranks": {0: 1, 1: 2, 2: 3}}, {"ranks": {0: 3, 1: 2, 2: 1}}),
        ("fake_or_real", {"verdicts": {0: "real"}}, {"verdicts": {0: "generated"}}),
        ("rating_reference", {"ratings": {0: 4, 1: 2, 2: 3}}, {"ratings": {0: 1, 1: 2, 2: 3}}),
        ("pairwise", {"choice": "left"}, {"choice": "right"}),
        ("pairwise_graded", {"choice": "left"}, {"choice": "right"}),
        ("best_of_k", {"pick": 0}, {"pick": 1}),
        ("mushra", {"scores": {0: 80, 1: 20}}, {"scores": {0: 10, 1: 20}}),
    ],
)
def test_a_repeated_trial_shows_the_same_clips_later_and_records_consistency(
    study_of, make_bot, study_type, same, different
):
    study = study_of(study_type, repeat_trials=1, trials_per_participant=3)
    bot = join(make_bot, study)
    trials = list(bot.participant().trials.order_by("index"))
    repeat = next(t for t in trials if t.kind == "repeat")
    original = repeat.repeat_of
    assert original.kind == "main" and original.index < repeat.index
    order = list(original.items.judged().order_by("position").values_list("stimulus", flat=True))
    again = list(repeat.items.judged().order_by("position").values_list("stimulus", flat=True))
    assert again == order[::-1]  # mirrored: a side or position habit shows
    tokens = set(original.items.values_list("token", flat=True))
    assert not tokens & set(repeat.items.values_list("token", flat=True))  # new URLs
    for consistent in (True, False):
        if not consistent:  # answer the repeat once more, differently
            Trial.objects.filter(pk=repeat.pk).update(answered_at=None, catch_passed=None)
            Participant.objects.update(completed_at=None, outcome="")
        while (trial := bot.participant().current_trial()) is not None:
            answers = same
            if trial.pk == repeat.pk:
                # Answer the same clips alike: map positions back through the mirror.
                answers = mirrored(same if consistent else different, len(order))
            bot.trial_page()
            bot.answer(bot.answer_data(trial, **answers))
            assert Trial.objects.get(pk=trial.pk).answered_at is not None
        assert Trial.objects.get(pk=repeat.pk).catch_passed is consistent
        # A changed answer is a reliability figure, not an exclusion (as in the analysis
        # by default): between two equally good clips a person may fairly change.
        assert Study.objects.with_counts().get().n_excluded == 0
        assert not bot.participant().excluded()


def mirrored(answers: dict, n: int) -> dict:
    flip = {"left": "right", "right": "left"}
    out = {}
    for name, value in answers.items():
        if name == "choice":
            out[name] = flip.get(value, value)
        elif name == "pick":
            out[name] = n - 1 - value if isinstance(value, int) else value
        else:
            out[name] = {n - 1 - position: v for position, v in value.items()}
    return out


# Reference clips and scoring standards


def test_the_reference_is_shown_never_rated(study_of, make_bot):
    study = study_of("rating_reference")
    references = set(study.stimuli.filter(role="reference").values_list("pk", flat=True))
    for _ in range(3):
        bot = join(make_bot, study)
    assert not TrialItem.objects.judged().filter(stimulus__in=references).exists()
    trial = bot.participant().current_trial()
    reference = trial.items.get(role="reference")
    assert reference.stimulus_id in references and reference.stimulus.action == trial.action
    assert reference.required
    page = bot.trial_page().content.decode()
    assert f"/c/{reference.token}.mp4" in page and "Reference" in page
    assert f'name="plays_{reference.token}"' in page
    assert f'name="rating_{reference.token}"' not in page


def test_the_scoring_standard_of_the_action_comes_before_the_clips(study_of, make_bot):
    study = study_of("rating_standards")
    bot = join(make_bot, study)
    trial = bot.participant().current_trial()
    page = bot.trial_page().content.decode()
    standards = list(study.standards.filter(action=trial.action).order_by("score"))
    assert [s.score for s in standards] == [1, 2, 3, 4, 5]
    examples = {i.stimulus_id: i for i in trial.items.filter(role="example")}
    positions = [page.index(f"/c/{examples[s.stimulus_id].token}.mp4") for s in standards]
    first_clip = min(page.index(f"/c/{i.token}.mp4") for i in trial.items.judged())
    assert positions == sorted(positions) and positions[-1] < first_clip
    assert standards[0].description in page
    assert all(item.required for item in examples.values())  # the first time: watched
    example_stimuli = study.stimuli.filter(role="example")
    assert not TrialItem.objects.judged().filter(stimulus__in=example_stimuli).exists()


def test_a_standard_needs_an_example_clip_of_its_study(study_of):
    from django.core.exceptions import ValidationError

    from studyapp.survey.models import ScoringStandard

    study = study_of("rating_standards")
    judged = study.stimuli.filter(role="judged").first()
    with pytest.raises(ValidationError, match="role 'example'"):
        standard = ScoringStandard(
            study=study, action="walk", score=1, description="x", stimulus=judged
        )
        standard.full_clean()


# Balance


@pytest.mark.parametrize("study_type", TYPES)
def test_assignment_is_balanced_for_every_type(media_root, make_bot, study_type, monkeypatch):
    # Participants' plans come from random seeds, and ties are broken by them: with six
    # participants the seats could differ by 3 once in a while. Seeds 1, 2, ... instead.
    seeds = itertools.count(1)
    monkeypatch.setattr("studyapp.survey.models.participation.secrets.randbits",
                        lambda bits: next(seeds))
    kind = get_study_type(study_type)
    clips = min(kind.default_clips_per_trial, len(SOURCES))
    study = Study.objects.create_study(study_type, "balanced", "Balanced", clips_per_trial=clips)
    make_stimuli(study, per_cell=2)
    for _ in range(6):
        join(make_bot, study)
    counts = Counter({s.pk: 0 for s in study.stimuli.all()})
    counts.update(TrialItem.objects.values_list("stimulus", flat=True))
    assert max(counts.values()) - min(counts.values()) <= spread(study), counts
    for trial in Trial.objects.all():
        sources = list(trial.items.values_list("stimulus__source", flat=True))
        assert len(set(sources)) == len(sources)  # one clip per source
    # Sources are counterbalanced over positions in main trials (a repeated trial shows its
    # first showing's seats again, a catch or practice trial is an extra on top).
    seats = Counter(TrialItem.objects.filter(trial__kind=Trial.Kind.MAIN)
                    .values_list("stimulus__source", "position"))
    for source in SOURCES:
        shown = [seats[source, p] for p in range(study.kind.items_per_trial(study))]
        assert max(shown) - min(shown) <= 2, (source, shown)  # pairwise: left and right


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("study_type", ["ranking", "pairwise"])
def test_concurrent_participants_still_get_balanced_trials(media_root, study_type):
    """Participants who start at the same moment must not read the same counts."""
    if connection.vendor == "sqlite" and connection.settings_dict["NAME"].startswith("file:memory"):
        pytest.skip("a shared-memory SQLite database cannot hold concurrent writers")
    clips = min(get_study_type(study_type).default_clips_per_trial, len(SOURCES))
    study = Study.objects.create_study(
        study_type, "concurrent", "Concurrent", clips_per_trial=clips
    )
    make_stimuli(study, per_cell=3)
    n, errors = 9, []
    barrier = threading.Barrier(n)

    def participate():
        try:
            bot = Bot(Client(), study)
            bot.enter()
            bot.consent()
            barrier.wait(timeout=30)
            bot.start()
        except Exception as error:  # reported below with the others
            errors.append(repr(error))
        finally:
            connection.close()

    threads = [threading.Thread(target=participate) for _ in range(n)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60)
    assert not errors
    assert Participant.objects.count() == n
    assert all(p.trials.exists() for p in Participant.objects.all())
    counts = Counter({s.pk: 0 for s in study.stimuli.all()})
    counts.update(TrialItem.objects.values_list("stimulus", flat=True))
    assert max(counts.values()) - min(counts.values()) <= spread(study), counts


# Blindness


def session_responses(bot, study):
    """Take a whole session, keeping every response, including a refused answer."""
    responses = [bot.enter(PROLIFIC_PID="blind"), bot.consent(), bot.start()]
    pages = []
    while (trial := bot.participant().current_trial()) is not None:
        pages.append(bot.trial_page())
        responses.append(pages[-1])
        responses.append(bot.answer(bot.answer_data(trial, plays=0)))
        responses.append(bot.answer(bot.answer_data(trial), follow=True))
    responses.append(bot.client.post(bot.url("about-you"), {"age_range": "18-24"}, follow=True))
    return responses, pages


@pytest.mark.parametrize("study_type", TYPES)
def test_nothing_a_participant_receives_names_a_source(study_of, make_bot, study_type):
    """Fetch every page, script, style sheet and clip of a session of every type."""
    study = study_of(
        study_type, slug="blind", catch=True, practice=True, repeat_trials=1, ask_demographics=True
    )
    bot = make_bot(study)
    responses, trial_pages = session_responses(bot, study)
    assert bot.participant().completed_at is not None and bot.participant().demographics
    texts, fetched = [], set()
    for response in responses:
        html = response.content.decode().replace(study.data_note, "")
        texts += [html, str(dict(response.items()))]
        for url in set(re.findall(r'(?:src|href|poster)="([^"]+)"', html)) - fetched:
            fetched.add(url)
            if url.startswith("/" + settings.STATIC_URL):
                texts.append(Path(finders.find(url.split(settings.STATIC_URL, 1)[1])).read_text())
            elif url.startswith("/c/"):
                clip = bot.client.get(url, HTTP_RANGE="bytes=0-")
                texts.append(str(dict(clip.items())))
                texts.append(b"".join(clip.streaming_content).decode("latin-1"))
    assert sum(url.startswith("/c/") for url in fetched) >= study.stimuli.count() // 2
    allowed = set(get_study_type(study_type).interface_words)
    labels = set(Stimulus.objects.values_list("source", flat=True))
    labels |= {"generated", "fake", "condgru"}
    labels |= {"is_catch", "catch_passed", "repeat_of", "stimulus_role", "video_hash"}
    for label in labels - allowed:
        for text in texts:
            assert not words(text, label), f"{label!r} leaks: {words(text, label)[:3]}"
    # Words the questions need ("real or generated") appear alike on every trial page.
    for label in allowed:
        counts = {len(words(page.content.decode(), label)) for page in trial_pages}
        assert len(counts) == 1, f"{label!r} appears {counts} times on different trial pages"


# Admin and preview


def test_admin_opens_closes_and_shows_progress(study_of, make_bot, admin_client):
    study = study_of("rating_standards", catch=True, max_failed_catch=0)
    bot = join(make_bot, study)
    bot.finish(ratings={0: 5, 1: 5, 2: 5})  # the broken clip gets 5 wherever it is
    listing = admin_client.get("/admin/survey/study/")
    assert b"field-excluded" in listing.content and b"/preview/" in listing.content
    change = admin_client.get(f"/admin/survey/study/{study.pk}/change/")
    text = change.content.decode()
    assert "1 started, 1 completed, 1 excluded" in text
    assert "Catch (an obviously broken clip)" in text and "Scoring standards" in text
    for action, status in (("close_studies", "closed"), ("open_studies", "open")):
        admin_client.post(
            "/admin/survey/study/", {"action": action, "_selected_action": [study.pk]}
        )
        assert Study.objects.get().status == status
    for path in ("/admin/survey/participant/", "/admin/survey/trial/?kind=catch",
                 "/admin/survey/response/?trial__kind=main", "/admin/survey/stimulus/?role=catch"):
        assert admin_client.get(path).status_code == 200, path


@pytest.mark.parametrize("study_type", TYPES)
def test_the_preview_walks_every_page_and_stores_nothing(
    study_of, admin_client, client, study_type
):
    study = study_of(study_type, catch=True, practice=True, ask_demographics=True, status="closed")
    before = (Participant.objects.count(), Trial.objects.count(), TrialItem.objects.count())
    assert client.get(f"/preview/{study.slug}/").status_code == 302  # to the admin login
    assert "/admin/login/" in client.get(f"/preview/{study.slug}/")["Location"]
    response = admin_client.get(f"/preview/{study.slug}/", follow=True)
    assert b"nothing you answer is stored" in response.content
    response = admin_client.post(f"/preview/{study.slug}/consent/", {"agree": "1"}, follow=True)
    response = admin_client.post(f"/preview/{study.slug}/instructions/", follow=True)
    answered = 0
    while response.redirect_chain[-1][0].endswith("/trial/"):
        html = response.content.decode()
        data = preview_answer(html, study_type)
        refused = admin_client.post(
            f"/preview/{study.slug}/trial/", data | {k: "0" for k in data if k.startswith("plays_")}
        )
        assert b"would not be accepted" in refused.content
        response = admin_client.post(f"/preview/{study.slug}/trial/", data, follow=True)
        answered += 1
    assert answered >= 2
    assert response.redirect_chain[-1][0].endswith("/about-you/")
    response = admin_client.post(
        f"/preview/{study.slug}/about-you/", {"age_range": "18-24"}, follow=True
    )
    assert b"PREVIEW" in response.content
    after = (Participant.objects.count(), Trial.objects.count(), TrialItem.objects.count())
    assert after == before == (0, 0, 0)


def preview_answer(html: str, study_type: str) -> dict:
    """Answer a preview trial page from its own form: every clip it plays, in order."""
    data = {"trial": re.search(r'name="trial" value="(\d+)"', html).group(1)}
    tokens = re.findall(r'name="plays_([\w-]+)"', html)
    data.update({f"plays_{token}": "1" for token in tokens})
    items = [SimpleNamespace(position=i, token=t, role="judged") for i, t in enumerate(tokens)]
    return data | get_study_type(study_type).answer_fields(items)
