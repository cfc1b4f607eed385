"""Best of K through the real pages: the trials planned, the answers checked, graded and
exported."""

import pytest

from studyapp.results.export import responses_frame
from studyapp.survey.models import Study, Trial
from studyapp.survey.study_types import get_study_type
from tests.studyapp.conftest import SOURCES, make_stimuli, make_study

pytestmark = pytest.mark.django_db


@pytest.fixture
def study_of(media_root, clips, extra_clips):
    return lambda **fields: make_study("best_of_k", clips, extra_clips, **fields)


def join(make_bot, study):
    bot = make_bot(study)
    bot.join()
    return bot


def test_k_clips_of_one_action_with_sources_balanced(media_root, make_bot):
    study = Study.objects.create_study("best_of_k", "best", "Best", options={"k": 3})
    make_stimuli(study, per_cell=2)
    assert study.kind.items_per_trial(study) == 3 and "shows 3 short" in study.instructions
    for _ in range(4):
        join(make_bot, study)
    for trial in Trial.objects.all():
        items = list(trial.items.select_related("stimulus"))
        assert len(items) == 3 and {i.stimulus.action for i in items} == {trial.action}
        assert sorted(i.stimulus.source for i in items) == sorted(SOURCES)
    two = Study.objects.create_study("best_of_k", "best-two", "Best", options={"k": 2})
    make_stimuli(two)
    join(make_bot, two)
    assert {t.items.count() for t in Trial.objects.filter(participant__study=two)} == {2}


def test_k_defaults_to_four_clips_and_is_checked():
    kind = get_study_type("best_of_k")
    study = Study.objects.create_study("best_of_k", "default-k", "Best")
    assert kind.items_per_trial(study) == 4 and "shows 4 short" in study.instructions
    with pytest.raises(ValueError, match="k: 1 must be at least 2"):
        kind.check_options({"k": 1})
    with pytest.raises(ValueError, match="k: '4' must be int"):
        kind.check_options({"k": "4"})


def test_the_page_offers_each_clip_and_all_good_and_all_bad(study_of, make_bot):
    bot = join(make_bot, study_of())
    trial = bot.participant().current_trial()
    page = bot.trial_page().content.decode()
    for item in trial.items.judged():
        assert f'name="pick" value="{item.token}"' in page
    assert 'value="all_good"' in page and 'value="all_bad"' in page
    assert "All good" in page and "All bad" in page


def test_a_pick_naming_a_clip_of_another_trial_is_refused(study_of, make_bot):
    study = study_of(trials_per_participant=2)
    bot = join(make_bot, study)
    first, second = bot.participant().trials.order_by("index")[:2]
    data = bot.answer_data(first) | {"pick": second.items.first().token}
    response = bot.answer(data)
    assert response.status_code == 400
    assert b"not one of the clips or choices offered" in response.content
    assert not Trial.objects.filter(answered_at__isnull=False).exists()


@pytest.mark.parametrize("pick, passed", [("other", True), ("catch", False),
                                           ("all_bad", True), ("all_good", False)])
def test_a_catch_trial_is_passed_by_another_clip_or_all_bad(study_of, make_bot, pick, passed):
    bot = join(make_bot, study_of(catch=True))
    while (trial := bot.participant().current_trial()) is not None:
        answer = 0
        if trial.kind == "catch":
            broken = trial.items.get(stimulus__role="catch").position
            answer = {"other": 1 if broken == 0 else 0, "catch": broken}.get(pick, pick)
        bot.trial_page()
        assert bot.answer(bot.answer_data(trial, pick=answer)).status_code == 302
    assert Trial.objects.get(kind="catch").catch_passed is passed


def test_the_export_marks_the_picked_clip_and_all_good_all_bad(study_of, make_bot):
    study = study_of(trials_per_participant=2)
    bot = join(make_bot, study)
    picks = iter([1, "all_good"])
    while (trial := bot.participant().current_trial()) is not None:
        bot.trial_page()
        bot.answer(bot.answer_data(trial, pick=next(picks)))
    table = responses_frame(study)
    by_trial = table.groupby("trial")["pick"].apply(list).to_dict()
    assert by_trial == {0: ["other", "best", "other"], 1: ["all_good"] * 3}
    first = table.loc[table["trial"] == 0]
    assert first.loc[first["pick"] == "best", "position"].tolist() == [1]
    stored = Trial.objects.order_by("index").values_list("answers", flat=True)
    assert list(stored) == [{"preference": 1}, {"preference": "all_good"}]
