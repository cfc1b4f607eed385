"""Graded pairwise preference through Django's test client: the scale offered, answers
stored and exported with their grades, tampered posts refused, catch and repeated trials
graded, and how bots answer."""

import random

import pytest

from studyapp.participation.bots import BradleyTerry, TrialPage
from studyapp.results.export import responses_frame
from studyapp.survey.models import Stimulus, Trial, TrialItem
from studyapp.survey.study_types import get_study_type
from studyapp.survey.study_types.base import Graded
from studyapp.survey.study_types.pairwise_graded import SCALE
from tests.studyapp.conftest import make_study

pytestmark = pytest.mark.django_db

KIND = get_study_type("pairwise_graded")
LABELS = ["A much better", "A better", "A slightly better", "No preference",
          "B slightly better", "B better", "B much better"]


@pytest.fixture
def study_of(media_root, clips, extra_clips):
    return lambda **fields: make_study("pairwise_graded", clips, extra_clips, **fields)


def join(make_bot, study):
    bot = make_bot(study)
    bot.join()
    return bot


def test_the_page_offers_the_seven_point_scale_and_both_bad_by_default(study_of, make_bot):
    study = study_of()
    assert study.option("both_bad") is True
    assert '"Both bad"' in study.instructions
    page = join(make_bot, study).trial_page().content.decode()
    for label in LABELS + ["Both bad"]:
        assert f"<span>{label}</span>" in page
    positions = [page.index(f"<span>{label}</span>") for label in LABELS]
    assert positions == sorted(positions)  # A's end first, B's last
    for key, (value, _, _) in enumerate(SCALE, 1):
        assert f'value="{value}" required data-key="{key}"' in page
    assert page.count('name="choice"') == 8


def test_both_bad_can_be_switched_off(study_of, make_bot):
    study = study_of(both_bad=False)
    assert "Both bad" not in study.instructions
    bot = join(make_bot, study)
    assert "Both bad" not in bot.trial_page().content.decode()
    trial = bot.participant().current_trial()
    assert bot.answer(bot.answer_data(trial, choice="both_bad")).status_code == 400
    assert not Trial.objects.filter(answered_at__isnull=False).exists()


def test_options_are_checked():
    with pytest.raises(ValueError, match="both_bad: 'yes' must be bool"):
        KIND.check_options({"both_bad": "yes"})
    with pytest.raises(ValueError, match="allow_ties: not an option of pairwise_graded"):
        KIND.check_options({"allow_ties": True})


def test_every_trial_shows_two_clips_of_one_action_from_two_sources(study_of, make_bot):
    study = study_of(trials_per_participant=4)
    for _ in range(3):
        join(make_bot, study)
    trials = Trial.objects.filter(kind="main")
    assert trials.count() == 12
    for trial in trials:
        items = list(trial.items.judged().select_related("stimulus").order_by("position"))
        assert [item.position for item in items] == [0, 1]
        assert len({item.stimulus.source for item in items}) == 2
        assert {item.stimulus.action for item in items} == {trial.action}


@pytest.mark.parametrize("choice, grade", [(v, g) for v, _, g in SCALE] + [("both_bad", None)])
def test_each_answer_is_stored_and_exported_with_the_grade_of_each_clip(
        study_of, make_bot, choice, grade):
    study = study_of(trials_per_participant=1)
    bot = join(make_bot, study)
    trial = bot.participant().current_trial()
    bot.trial_page()
    assert bot.answer(bot.answer_data(trial, choice=choice)).status_code == 302
    assert Trial.objects.get(pk=trial.pk).answers == {"preference": choice}
    table = responses_frame(study).sort_values("position")
    assert table["choice"].tolist() == [choice, choice]
    assert table["study_type"].tolist() == ["pairwise_graded"] * 2
    if grade is None:
        assert table["grade"].isna().all()
    else:
        assert table["grade"].tolist() == [grade, -grade]


@pytest.mark.parametrize("tampering", [
    lambda d: d | {"choice": "much_better"},
    lambda d: d | {"choice": "both_good"},  # pairwise's tie is not on this scale
    lambda d: d | {"choice": "3"},
    lambda d: {k: v for k, v in d.items() if k != "choice"},
    lambda d: d | {"rank_someoneelsesclip": "1"},
])
def test_a_tampered_answer_is_refused(study_of, make_bot, tampering):
    bot = join(make_bot, study_of())
    trial = bot.participant().current_trial()
    bot.trial_page()
    response = bot.answer(tampering(bot.answer_data(trial)))
    assert response.status_code == 400
    assert not Trial.objects.filter(answered_at__isnull=False).exists()


def test_the_message_of_a_missing_answer_names_what_to_do(study_of, make_bot):
    bot = join(make_bot, study_of())
    trial = bot.participant().current_trial()
    bot.trial_page()
    data = {k: v for k, v in bot.answer_data(trial).items() if k != "choice"}
    assert b"No point of the scale is chosen yet." in bot.answer(data).content


# Grading, on unsaved rows


def pair(choice, catch_at=None, ids=(1, 2)):
    """Return a graded trial of two clips (stimulus ids ``ids``, left first)."""
    trial = Trial(answers={"preference": choice})
    items = []
    for position, pk in enumerate(ids):
        role = Stimulus.Role.CATCH if position == catch_at else Stimulus.Role.JUDGED
        items.append(TrialItem(trial=trial, position=position, stimulus=Stimulus(pk=pk, role=role)))
    return Graded(trial, items, "preference")


@pytest.mark.parametrize("catch_at", [0, 1])
def test_a_catch_trial_is_passed_only_when_the_intact_clip_is_judged_better(catch_at):
    for value, _, grade in SCALE:
        intact_grade = grade if catch_at == 1 else -grade
        assert KIND.catch_passed(pair(value, catch_at)) is (intact_grade > 0), value
    assert KIND.catch_passed(pair("both_bad", catch_at)) is False


def test_a_repeat_is_consistent_within_one_step_and_on_the_same_side():
    # The repeat shows the clips mirrored: stimulus 1 moves from left to right.
    def consistent(first, again):
        return KIND.consistent(pair(first), pair(again, ids=(2, 1)))

    assert consistent("left", "right")  # the same clip "better" both times
    assert consistent("left", "right_much") and consistent("left_much", "right")
    assert not consistent("left_much", "right_slightly")  # two steps apart
    assert consistent("left_slightly", "no_preference")
    assert not consistent("left_slightly", "left_slightly")  # the other clip, now
    assert consistent("no_preference", "no_preference")
    assert consistent("both_bad", "both_bad") and not consistent("both_bad", "no_preference")


# Bots


def test_bots_grade_by_their_strengths_and_say_both_bad_only_when_offered():
    rng = random.Random(0)
    policy = BradleyTerry(rng, {"real": 20.0, "gen": 1.0}, sources=["real", "gen"])
    values = [v for v, _, _ in SCALE]
    page = TrialPage({}, ["a", "b"], values + ["both_bad"], sources={"a": "real", "b": "gen"})
    answers = [KIND.bot_answer(page, policy)["choice"] for _ in range(400)]
    assert set(answers) <= set(values) | {"both_bad"}
    grades = [dict((v, g) for v, _, g in SCALE)[a] for a in answers if a != "both_bad"]
    assert sum(grades) / len(grades) > 1.5  # real (left) judged clearly better
    assert len(set(answers)) >= 4  # graded, not only the extremes
    plain = TrialPage({}, ["a", "b"], values, sources={"a": "gen", "b": "gen"})
    assert "both_bad" not in {KIND.bot_answer(plain, policy)["choice"] for _ in range(400)}


# From the pages to the report


def test_stored_answers_are_analysed_by_the_analyze_command(study_of, make_bot, tmp_path):
    """Participants who always grade the real clip better, by three steps over cond_gru and
    one over a2m: the report orders the sources so and notes the few participants."""
    import json

    from django.core.management import call_command

    study = study_of()
    strength = {"real": 3, "a2m": 2, "cond_gru": 0}
    for _ in range(3):
        bot = join(make_bot, study)
        while (trial := bot.participant().current_trial()) is not None:
            left, right = (item.stimulus.source for item in
                           trial.items.judged().select_related("stimulus").order_by("position"))
            gap = max(-3, min(3, strength[left] - strength[right]))
            choice = next(value for value, _, g in SCALE if g == gap)
            bot.trial_page()
            assert bot.answer(bot.answer_data(trial, choice=choice)).status_code == 302
    out = tmp_path / "report"
    call_command("analyze", study=study.slug, out=str(out), bootstrap=50, no_audit=True,
                 min_time_factor=0.0)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["study_type"] == "pairwise_graded"
    assert summary["order"] == ["real", "a2m", "cond_gru"]
    assert any("fewer than 10 participants" in note for note in summary["notes"])
    assert (out / "position_bias.csv").is_file() and (out / "pairs.csv").is_file()
