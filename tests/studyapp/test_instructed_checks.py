"""Instructed-response checks, the contract every study type keeps: a trial whose text
says exactly which answer to give, planned like catch trials (never first), said,
graded and obeyed through the type's hooks, exported as its own trial kind and left out
of the judgements by the analysis."""

import random

import pytest
from django.test import Client
from django.utils.html import escape

from analysis.study import AnalysisConfig, analyse_all
from studyapp.participation.bots import TrialPage, contrary
from studyapp.results.export import participants_frame, responses_frame
from studyapp.survey.models import Trial
from studyapp.survey.study_types import list_study_types
from tests.studyapp.conftest import make_study

pytestmark = pytest.mark.django_db

TYPES = list_study_types()


def answer_fields(data: dict) -> dict:
    """Return the answer fields of a trial's POST (what ``StudyType.obey`` changes)."""
    return {k: v for k, v in data.items() if k not in ("trial", "events")
            and not k.startswith("plays_")}


def take(bot, study, obey: bool, rng) -> Trial:
    """Answer every trial of ``bot``; the instructed check as asked, or as another
    instruction asks; return the check."""
    kind = study.kind
    check = None
    while (trial := bot.participant().current_trial()) is not None:
        page = bot.trial_page()
        data = bot.answer_data(trial)
        if trial.kind == Trial.Kind.INSTRUCTED:
            check = trial
            judged = list(trial.items.filter(role="judged").order_by("position"))
            said = kind.instruction_sentence(study, trial, judged)
            assert said.startswith("This is an attention check: ")
            assert escape(said) in page.content.decode()
            asked = trial.instruction if obey else contrary(study, trial.instruction,
                                                            len(judged), rng)
            view = TrialPage({}, [item.token for item in judged], [])
            data.update(kind.obey(view, asked, answer_fields(data)))
        assert bot.answer(data).status_code == 302
    return check


@pytest.mark.parametrize("study_type", TYPES)
def test_every_type_says_grades_and_obeys_an_instructed_check(media_root, clips, extra_clips,
                                                             make_bot, study_type):
    study = make_study(study_type, clips, extra_clips, instructed_checks=2, max_failed_catch=1)
    rng = random.Random(0)
    for obey in (True, False):
        bot = make_bot(study)
        bot.join()
        trials = list(bot.participant().trials.order_by("index"))
        checks = [t for t in trials if t.kind == Trial.Kind.INSTRUCTED]
        assert len(checks) == 2 and trials[0].kind == Trial.Kind.MAIN  # never first
        assert all(t.instruction for t in checks) and not any(
            t.instruction for t in trials if t.kind != Trial.Kind.INSTRUCTED)
        take(bot, study, obey, rng)
        graded = set(Trial.objects.filter(pk__in=[t.pk for t in checks])
                     .values_list("catch_passed", flat=True))
        assert graded == {obey}
        assert bot.participant().outcome == ("completed" if obey else "failed_attention")

    table = responses_frame(study)
    assert set(table["trial_kind"]) == {"main", "instructed"}
    checked = table.loc[table["trial_kind"] == "instructed"]
    assert checked["catch_passed"].notna().all()
    main = table.loc[table["trial_kind"] == "main"]
    people = participants_frame(study)
    assert people["n_catch"].tolist() == [2, 2] and people["failed_catch"].tolist() == [0, 2]
    # The analysis leaves the checks out of the judgements, and the participant who
    # failed them out altogether (more than max_failed_catch=1 failed checks).
    result = analyse_all(table, AnalysisConfig(bootstrap=0, min_time_factor=0,
                                               max_failed_catch=1,
                                               type_options={"screen_share": 1.0}))[0]
    obeyed = people.loc[people["failed_catch"] == 0, "participant"].iloc[0]
    assert result.counts["judgements"] == (main["participant"] == obeyed).sum()


def test_the_preview_shows_an_instructed_check(media_root, clips, admin_client):
    study = make_study("pairwise", clips, instructed_checks=1, trials_per_participant=1)
    admin_client.get(f"/preview/{study.slug}/")
    admin_client.post(f"/preview/{study.slug}/consent/", {"agree": "1"})
    admin_client.post(f"/preview/{study.slug}/instructions/")
    pages = []
    for index in range(2):
        page = admin_client.get(f"/preview/{study.slug}/trial/").content.decode()
        pages.append(page)
        choice = "left"
        if "attention check" in page:
            choice = "right" if "\u201cRight\u201d" in page else "left"
        plays = {f"plays_preview-{index}-{position}": "1" for position in range(2)}
        answered = admin_client.post(f"/preview/{study.slug}/trial/",
                                     {"trial": str(index), "choice": choice, **plays})
        assert answered.status_code == 302
    assert sum("This is an attention check: choose" in page for page in pages) == 1
    assert "This is an attention check" not in pages[0]
    assert Client().get(f"/preview/{study.slug}/").status_code == 302  # staff only
