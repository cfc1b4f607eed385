"""The balanced planner's kept counts (``Balance``) always equal what the study's items say.

A start reads the kept counts instead of every item of the study; these tests hold them
against the aggregate over the items (``shown_counts(study)``, what every start read before)
after starts, deletions and items made outside a start.
"""

import pytest

from studyapp.survey.models import Balance, Participant, Trial, TrialItem
from studyapp.survey.models.participation import Tally, shown_counts
from tests.studyapp.conftest import make_ranking_study


def start(study, key):
    person = Participant.objects.enroll(study, {}, key)
    Participant.objects.start(person)
    return person


def assert_kept_counts_are_the_items(study):
    _, items, positions, _ = shown_counts(study)
    tally = Tally.read(study)
    if Balance.objects.filter(pk=study.pk).exists():
        assert tally.unstored == set(), "a start left items uncounted"
    assert +tally.items == +items and +tally.positions == +positions


@pytest.fixture
def study(db, media_root, clips):
    return make_ranking_study(clips, trials_per_participant=3, repeat_trials=1)


def test_starts_keep_the_counts_of_every_main_item(study):
    for i in range(6):
        start(study, f"p{i}")
        assert_kept_counts_are_the_items(study)
    assert Balance.objects.filter(pk=study.pk).exists()
    # The repeats are not counted (only main trials are balanced).
    assert sum(Tally.read(study).items.values()) == TrialItem.objects.judged().filter(
        trial__participant__study=study, trial__kind=Trial.Kind.MAIN).count()


def test_deleting_a_participant_counts_the_study_afresh(study):
    people = [start(study, f"p{i}") for i in range(4)]
    people[1].delete()
    assert not Balance.objects.filter(pk=study.pk).exists()
    assert_kept_counts_are_the_items(study)  # read from the items while nothing is kept
    start(study, "after")
    assert Balance.objects.filter(pk=study.pk).exists()
    assert_kept_counts_are_the_items(study)
    Participant.objects.filter(study=study, external_key__in=["p0", "p2"]).delete()
    start(study, "later")
    assert_kept_counts_are_the_items(study)


def test_a_main_trial_made_outside_a_start_is_counted_by_the_next(study):
    person = start(study, "p0")
    start(study, "p1")
    trial = Trial.objects.create(participant=person, index=99, action="extra")
    stimuli = list(study.stimuli.judged()[:2])
    TrialItem.objects.bulk_create(TrialItem(trial=trial, stimulus=s, position=i)
                                  for i, s in enumerate(stimuli))
    tally = Tally.read(study)
    assert {(s.pk, i) for i, s in enumerate(stimuli)} <= tally.unstored
    _, items, positions, _ = shown_counts(study)
    assert +tally.items == +items and +tally.positions == +positions  # seen before stored
    start(study, "p2")
    assert_kept_counts_are_the_items(study)


def test_deleting_the_study_deletes_its_counts(study):
    start(study, "p0")
    study.participants.all().delete()  # as the demo does (stimuli protect their items)
    study.delete()
    assert not Balance.objects.exists()


def test_the_admin_deletes_a_participant_whole_never_a_trial_or_an_answer(study, admin_client):
    person = start(study, "p0")
    start(study, "p1")
    trial = person.trials.filter(kind=Trial.Kind.MAIN).first()
    item = trial.items.first()
    for path in (f"/admin/survey/trial/{trial.pk}/delete/",
                 f"/admin/survey/response/{item.pk}/delete/"):
        assert admin_client.get(path).status_code == 403, path
    response = admin_client.post("/admin/survey/trial/", {
        "action": "delete_selected", "_selected_action": [trial.pk], "post": "yes"})
    assert response.status_code in (200, 302, 403)
    assert Trial.objects.filter(pk=trial.pk).exists()
    response = admin_client.post(f"/admin/survey/participant/{person.pk}/delete/",
                                 {"post": "yes"})
    assert response.status_code == 302 and not Participant.objects.filter(pk=person.pk).exists()
    start(study, "p2")
    assert_kept_counts_are_the_items(study)


def test_deleting_someone_without_main_trials_keeps_the_counts(study):
    start(study, "p0")
    practice_only = Participant.objects.enroll(study, {}, "audit")
    Trial.objects.create(participant=practice_only, index=0, action="audit",
                         kind=Trial.Kind.PRACTICE)
    practice_only.delete()  # as the blindness audit deletes its own participants
    assert Balance.objects.filter(pk=study.pk).exists()
    assert_kept_counts_are_the_items(study)
