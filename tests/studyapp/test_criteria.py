"""Trials that ask several questions of the same clips (``criteria``), for every type: the
config, the trial page, the server's checks, storage, the export and the analysis."""

import json

import pytest
from django.core.management import call_command

from analysis.study import AnalysisConfig, analyse_all
from studyapp.results.export import responses_frame
from studyapp.survey.models import Trial
from studyapp.stimuli.config import ConfigError, parse
from studyapp.survey.study_types.base import check_criteria, criterion_of
from tests.studyapp.conftest import make_study
from tests.studyapp.test_build_stimuli import small

pytestmark = pytest.mark.django_db

CRITERIA = ["naturalness", "fit to the action"]
KEYS = ["naturalness", "fit_to_the_action"]
QUESTIONS = ["Naturalness", "Fit to the action"]
TYPES = ["ranking", "rating_standards", "rating_reference", "pairwise", "fake_or_real"]
# The answer field of each type (per clip, or on the trial for pairwise).
PREFIX = {"ranking": "rank_", "rating_standards": "rating_", "rating_reference": "rating_",
          "fake_or_real": "judged_", "pairwise": "choice"}
EXPORTED = {"ranking": "rank", "rating_standards": "rating", "rating_reference": "rating",
            "fake_or_real": "judged_real", "pairwise": "choice"}


def two_questions(study_type, clips, extra_clips, **fields):
    return make_study(study_type, clips, extra_clips, criteria=list(CRITERIA), **fields)


ORDER = ["real", "a2m", "cond_gru"]  # the first question's preference; the second's reversed


def answer_fields(data, study_type):
    return {k: v for k, v in data.items()
            if k.startswith(PREFIX[study_type]) and k != "trial"}


def preferring(trial, study_type, order, key=""):
    """Return answer fields for ``trial`` that prefer sources in ``order`` (best first),
    named for the question ``key`` ("" for the first)."""
    judged = list(trial.items.judged().select_related("stimulus").order_by("position"))
    place = {item.token: order.index(item.stimulus.source) for item in judged}
    prefix = f"{key}." if key else ""
    if study_type == "pairwise":
        left, right = judged
        return {f"{prefix}choice": "left" if place[left.token] < place[right.token] else "right"}
    out = {}
    ranked = sorted(place, key=place.get)
    for token in place:
        if study_type == "ranking":
            value = ranked.index(token) + 1
        elif study_type.startswith("rating"):
            value = 5 - 2 * place[token]
        else:
            value = "real" if place[token] == 0 else "generated"
        out[f"{prefix}{PREFIX[study_type]}{token}"] = str(value)
    return out


def both(bot, trial, study_type):
    """Return a full post answering both questions, with opposite preferences."""
    data = {k: v for k, v in bot.answer_data(trial).items()
            if k not in answer_fields(bot.answer_data(trial), study_type)}
    return (data | preferring(trial, study_type, ORDER)
            | preferring(trial, study_type, ORDER[::-1], KEYS[1]))


def test_criteria_are_texts_or_key_and_question():
    assert [criterion_of(c) .key for c in CRITERIA] == KEYS
    assert [criterion_of(c).text for c in CRITERIA] == QUESTIONS
    spelled = criterion_of({"key": "fit", "question": "How well does it show the action?"})
    assert (spelled.key, spelled.text) == ("fit", "How well does it show the action?")
    assert criterion_of({"key": "smooth_motion"}).text == "Smooth motion"
    assert check_criteria(CRITERIA) is None
    assert "'naturalness' is used twice" in check_criteria(["naturalness", "Naturalness"])
    assert "must start with a letter" in check_criteria(["3d look"])
    assert "list of questions" in check_criteria("naturalness")


@pytest.mark.parametrize("study_type", TYPES)
def test_a_config_with_two_criteria_is_read_for_every_type(tmp_path, study_type):
    config = parse(small(study={"type": study_type, "criteria": CRITERIA}), tmp_path)
    assert config.study_options["criteria"] == CRITERIA
    with pytest.raises(ConfigError, match="study.criteria: the key 'fit' is used twice"):
        parse(small(study={"type": study_type, "criteria": ["fit", {"key": "fit"}]}), tmp_path)


@pytest.mark.parametrize("study_type", ["ranking", "rating_reference", "pairwise"])
def test_a_two_criterion_config_builds_a_study_asking_both(tmp_path, media_root, study_type,
                                                           make_bot):
    from studyapp.stimuli.build import build_stimuli

    raw = small(slug=f"two-{study_type.replace('_', '-')}", sources=["real", "cond_gru"],
                study={"type": study_type, "criteria": CRITERIA})
    result = build_stimuli(parse(raw, tmp_path), tmp_path / "build")
    study = result.study
    assert [c.key for c in study.kind.criteria(study)] == KEYS
    assert [c.text for c in study.kind.criteria(study)] == QUESTIONS
    assert study.stimuli.filter(role="judged").count() >= 4
    bot = make_bot(study)
    bot.join()
    page = bot.trial_page().content.decode()
    assert all(question in page for question in QUESTIONS)


@pytest.mark.parametrize("study_type", TYPES)
def test_each_question_has_its_labelled_field_and_both_are_required(
        study_type, media_root, clips, extra_clips, make_bot):
    study = two_questions(study_type, clips, extra_clips)
    bot = make_bot(study)
    bot.join()
    trial = bot.participant().current_trial()
    page = bot.trial_page().content.decode()
    first = preferring(trial, study_type, ORDER)
    second = preferring(trial, study_type, ORDER[::-1], KEYS[1])
    for question in QUESTIONS:
        assert question in page
    if study_type != "fake_or_real":
        assert "each of the 2 questions below" in page
    for name in [*first, *second]:
        assert f'name="{name}"' in page

    # The second question left out: refused, naming the question; nothing is stored.
    data = both(bot, trial, study_type)
    response = bot.answer({k: v for k, v in data.items() if k not in second})
    assert response.status_code == 400
    assert "Fit to the action" in response.content.decode()
    assert not Trial.objects.filter(answered_at__isnull=False).exists()

    # Both answered: stored under each key.
    assert bot.answer(data).status_code == 302
    trial.refresh_from_db()
    judged = list(trial.items.judged().order_by("position"))
    # Opposite preferences give other answers, except fake_or_real's one clip of the middle
    # source (generated by either order).
    middle = study_type == "fake_or_real" and [i.stimulus.source for i in judged] == [ORDER[1]]
    if study_type == "pairwise":
        assert trial.answers == {KEYS[0]: first["choice"], KEYS[1]: second[f"{KEYS[1]}.choice"]}
    else:
        assert all(set(item.answers) == set(KEYS) for item in judged)
        answers = [[item.answers[key] for item in judged] for key in KEYS]
        assert answers[0] != answers[1] or middle

    # The export: one row per judged clip and question, with a criterion column.
    table = responses_frame(study)
    assert len(table) == 2 * len(judged)
    assert table["criterion"].tolist() == KEYS * len(judged)
    column = EXPORTED[study_type]
    by_key = {key: table.loc[table["criterion"] == key, column].tolist() for key in KEYS}
    assert by_key[KEYS[0]] != by_key[KEYS[1]] or middle


def test_a_broken_second_answer_names_its_question(media_root, clips, extra_clips, make_bot):
    study = two_questions("ranking", clips, extra_clips)
    bot = make_bot(study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    data = bot.answer_data(trial)
    second = {f"{KEYS[1]}.{k}": "1" for k in answer_fields(data, "ranking")}  # all rank 1
    response = bot.answer(data | second)
    assert response.status_code == 400
    assert "Fit to the action: Rank 1 is given to more than one clip" in response.content.decode()


@pytest.mark.parametrize("study_type", ["ranking", "rating_standards", "pairwise", "fake_or_real"])
def test_each_question_is_analysed_and_reported_on_its_own(
        study_type, media_root, clips, extra_clips, make_bot, tmp_path):
    study = two_questions(study_type, clips, extra_clips, trials_per_participant=2)
    for n in range(3):
        bot = make_bot(study)
        bot.join(PROLIFIC_PID=f"p{n}")
        while (trial := bot.participant().current_trial()) is not None:
            bot.trial_page()
            assert bot.answer(both(bot, trial, study_type)).status_code == 302
    # The test client answers at once: faster than the clips last, which would exclude it.
    results = analyse_all(responses_frame(study), AnalysisConfig(bootstrap=20, min_time_factor=0))
    assert [r.criterion for r in results] == KEYS
    assert all(r.counts["participants"] == 3 for r in results)
    assert results[0].analysis.sources.index[0] == "real"
    assert results[1].analysis.sources.index[0] == "cond_gru"

    out = tmp_path / "report"
    call_command("analyze", study=study.slug, out=str(out), bootstrap=20, no_audit=True,
                 min_time_factor=0)
    index = (out / "report.html").read_text()
    for key in KEYS:
        assert f'href="{key}/report.html"' in index
        summary = json.loads((out / key / "summary.json").read_text())
        assert summary["criterion"] == key
        assert (out / key / "report.html").is_file() and (out / key / "sources.csv").is_file()
    exported = (out / "responses.csv").read_text().splitlines()
    assert "criterion" in exported[0].split(",")


@pytest.mark.django_db(transaction=True)
def test_the_admin_shows_the_report_of_each_question(
        media_root, clips, extra_clips, make_bot, admin_client, settings, tmp_path):
    from studyapp.results.analysis_page import report_folder

    settings.VAR_DIR = tmp_path
    study = two_questions("rating_standards", clips, extra_clips, trials_per_participant=1)
    for n in range(2):
        bot = make_bot(study)
        bot.join(PROLIFIC_PID=f"p{n}")
        trial = bot.participant().current_trial()
        bot.trial_page()
        assert bot.answer(both(bot, trial, "rating_standards")).status_code == 302
    call_command("analyze", study=study.slug, out=str(report_folder(study)), bootstrap=10,
                 no_audit=True, min_time_factor=0)
    base = f"/admin/survey/study/{study.pk}/results/report/"
    index = b"".join(admin_client.get(base).streaming_content).decode()
    for key, question in zip(KEYS, QUESTIONS):
        assert f'href="{key}/report.html"' in index
        shown = admin_client.get(f"{base}{key}/report.html")
        assert shown.status_code == 200
        assert f"({key})" in b"".join(shown.streaming_content).decode()
    assert admin_client.get(f"{base}elsewhere/report.html").status_code == 404
    # No path leads out of the study's folder (no route matches: Django adds a slash).
    assert admin_client.get(f"{base}..%2Fnaturalness/report.html").status_code in (301, 404)
