"""A study's duration comes from the study: its trials, their clips' lengths and the type's
answer time; once enough participants completed, their median session time. Consent,
time limits and the Prolific draft follow from it."""

from datetime import timedelta

import pytest
from django.utils import timezone

from studyapp.participation import duration
from studyapp.survey.models import Participant, Stimulus, Study
from studyapp.crowd.prolific.draft import DraftOptions, draft_payload
from studyapp.survey.study_types import list_study_types
from tests.studyapp.conftest import make_stimuli

pytestmark = pytest.mark.django_db

# The example: the model's default study type (three clips ranked per trial).
EXAMPLE = Study._meta.get_field("study_type").default


def ranking(slug, actions=("walk", "wave"), seconds=1.0, **fields):
    study = Study.objects.create_study(EXAMPLE, slug, "Movement study", clips_per_trial=3,
                                       **fields)
    make_stimuli(study, actions=actions)
    Stimulus.objects.filter(study=study).update(duration=seconds)
    return study


def test_four_short_trials_take_about_a_minute_or_two_not_eight():
    study = ranking("short", actions=("walk", "wave", "jump", "sit"), seconds=2.0)
    found = study.duration()
    assert found.trials == 4 and found.measured is None
    # 4 trials x (3 clips x 2 s + 3 answers x 4 s + reading) and the pages around them
    assert 60 < found.estimate < 180
    assert study.minutes() == 2
    assert f"It takes about {study.minutes()} minutes." in study.shown_consent()


def test_the_estimate_grows_with_trials_clip_length_and_extra_trials():
    base = ranking("base").duration().estimate
    longer_clips = ranking("long", seconds=4.0).duration().estimate
    more = ranking("more", actions=("walk", "wave", "jump", "sit", "run", "kick"))
    checked = ranking("checked", repeat_trials=1)
    assert longer_clips - base == pytest.approx(2 * 3 * 3.0)  # 2 trials x 3 clips x 3 s
    assert more.duration().estimate > base and more.duration().trials == 6
    assert checked.duration().trials == 3 and checked.duration().estimate > base


@pytest.mark.parametrize("key", list_study_types())
def test_every_type_estimates_from_its_own_answer_time(key):
    from studyapp.survey.study_types import get_study_type

    kind = get_study_type(key)
    study = Study(study_type=key, clips_per_trial=3)
    assert kind.answer_time(study, 3) > 0
    one, twenty = (duration.config_minutes(study, n, 2.0) for n in (1, 20))
    assert 1 <= one < twenty <= 15


def complete(study, minutes, n):
    now = timezone.now()
    for k in range(n):
        Participant.objects.create(study=study, seed=k, consented_at=now,
                                   completed_at=now + timedelta(minutes=minutes[k % len(minutes)]),
                                   outcome=Participant.Outcome.COMPLETED)


def test_the_measured_median_replaces_the_estimate_after_five_completions():
    study = ranking("piloted", crowd={"platform": "prolific",
                                      "codes": {"completed": "C1", "no_consent": "N1"}})
    estimated = study.minutes()
    complete(study, [6, 7, 9], duration.MEASURED_AFTER - 1)
    assert study.duration().measured is None and study.minutes() == estimated
    complete(study, [7], 1)
    found = study.duration()
    assert found.n_measured == duration.MEASURED_AFTER and found.measured == 7 * 60
    assert study.minutes() == 7 and "It takes about 7 minutes." in study.shown_consent()
    # Prolific's default limit: 3 x the measured 7 minutes (at least its minimum).
    assert study.time_limit() == timedelta(minutes=21)
    assert "measured 7 min 00 s (median of 5" in found.describe()


def test_the_prolific_draft_asks_for_the_studys_minutes_at_the_hourly_rate():
    study = ranking("paid", max_participants=10)
    payload = draft_payload(study, {"completed": "C1"},
                            DraftOptions(base_url="https://study.example", hourly_cents=900))
    minutes = study.minutes()
    assert minutes <= 2
    assert payload["estimated_completion_time"] == minutes
    assert payload["reward"] == -(-minutes * 900 // 60)


def test_the_admin_shows_the_estimate_beside_the_measured_median(admin_client):
    study = ranking("shown")
    text = admin_client.get(f"/admin/survey/study/{study.pk}/change/").content.decode()
    assert f"{study.minutes()} minutes (estimated): estimated " in text
    assert "measured after 5 completed participants (0 so far)" in text
    # Progress comes before the settings form.
    assert text.index("Session length") < text.index('name="clips_per_trial"')
    complete(study, [4], duration.MEASURED_AFTER)
    text = admin_client.get(f"/admin/survey/study/{study.pk}/change/").content.decode()
    assert "4 minutes (measured): measured 4 min 00 s (median of 5 completed" in text
