"""MUSHRA through the real pages: the hidden reference and low anchor planned among the
clips and never named, sliders that must be moved, options checked, the export, and the
study's screening options reaching the analysis."""

import json
import re
from collections import Counter

import pytest
from django.core.management import call_command

from studyapp.results.export import responses_frame
from studyapp.survey.models import Trial
from studyapp.survey.study_types import get_study_type
from tests.studyapp.conftest import SOURCES, make_study

pytestmark = pytest.mark.django_db


@pytest.fixture
def study_of(media_root, clips, extra_clips):
    return lambda **fields: make_study("mushra", clips, extra_clips, **fields)


def join(make_bot, study):
    bot = make_bot(study)
    bot.join()
    return bot


def test_every_trial_hides_the_reference_and_the_anchor_among_the_clips(study_of, make_bot):
    study = study_of(catch=True, practice=True)
    places = Counter()
    for _ in range(6):
        join(make_bot, study)
    for trial in Trial.objects.exclude(kind="practice"):
        items = list(trial.items.select_related("stimulus").order_by("position"))
        roles = Counter(item.stimulus.role for item in items)
        assert roles["reference"] == 1 and roles["anchor"] == 1
        assert all(item.role == "judged" and item.required for item in items)
        assert {item.stimulus.action for item in items} == {trial.action}
        places.update(item.position for item in items if item.stimulus.role == "reference")
        if trial.kind == "main":
            assert sorted(i.stimulus.source for i in items if i.stimulus.role == "judged") == \
                sorted(SOURCES)
    assert len(places) >= 3  # shuffled in, not always in one place
    practice = Trial.objects.filter(kind="practice").first()
    assert set(practice.items.values_list("stimulus__role", flat=True)) == {"practice"}


def test_every_clip_visits_every_place_about_equally(media_root, make_bot, clips, extra_clips):
    study = make_study("mushra", clips, extra_clips, slug="seats", trials_per_participant=2)
    for _ in range(10):
        join(make_bot, study)
    seats = Counter()  # the hidden reference counts as its source (real), as assignment does
    for trial in Trial.objects.filter(kind="main"):
        for item in trial.items.select_related("stimulus"):
            seats[item.stimulus.source, item.position] += 1
    assert {source for source, _ in seats} == set(SOURCES) | {"anchor"}
    for source in set(SOURCES) | {"anchor"}:
        shown = [seats[source, p] for p in range(5)]
        assert max(shown) - min(shown) <= 2, (source, shown)


def test_the_page_names_neither_and_starts_every_slider_without_a_score(study_of, make_bot):
    bot = join(make_bot, study_of())
    trial = bot.participant().current_trial()
    page = bot.trial_page().content.decode()
    assert "Reference" not in page and "reference" not in page.lower().replace("aria-", "")
    assert "anchor" not in page.lower()
    for item in trial.items.all():
        assert f'name="score_{item.token}"' in page
    boxes = re.findall(r'<input type="number"[^>]*>', page)
    assert page.count('type="range"') == len(boxes) == trial.items.count()
    assert all("required" in box and "value=" not in box for box in boxes)  # no score yet
    assert "Clip E" in page  # five clips: three sources, the hidden reference and the anchor


def test_an_untouched_slider_is_refused_with_a_clear_message(study_of, make_bot):
    bot = join(make_bot, study_of())
    trial = bot.participant().current_trial()
    bot.trial_page()
    data = bot.answer_data(trial)
    untouched = next(item for item in trial.items.order_by("position"))
    del data[f"score_{untouched.token}"]
    response = bot.answer(data)
    assert response.status_code == 400
    assert b"Clip A has no score yet: move its slider." in response.content
    assert bot.answer(bot.answer_data(trial)).status_code == 302


def test_options_are_checked():
    kind = get_study_type("mushra")
    assert kind.check_options({"screen_share": 0}) == {"screen_share": 0.0}
    with pytest.raises(ValueError, match="screen_threshold: 120 must lie in 0..100"):
        kind.check_options({"screen_threshold": 120})
    with pytest.raises(ValueError, match="screen_share: 1.5 must lie in 0..1"):
        kind.check_options({"screen_share": 1.5})
    with pytest.raises(ValueError, match="screen_cutoff: not an option of mushra"):
        kind.check_options({"screen_cutoff": 90})


def test_the_export_has_a_row_per_clip_with_its_role_and_score(study_of, make_bot):
    study = study_of(trials_per_participant=2)
    bot = join(make_bot, study)
    while (trial := bot.participant().current_trial()) is not None:
        bot.trial_page()
        bot.answer(bot.answer_data(trial, scores={0: 0, 1: 100}))
    table = responses_frame(study)
    assert len(table) == 2 * 5
    assert Counter(table["stimulus_role"]) == {"judged": 6, "reference": 2, "anchor": 2}
    assert table.groupby("trial")["score"].apply(list).tolist() == [[0, 100, 50, 50, 50]] * 2


def test_the_studys_screening_options_reach_the_analysis(study_of, make_bot, tmp_path):
    # Every participant scores the hidden reference 70: out under the default 90, kept
    # under the study's own threshold of 60.
    for slug, options in (("strict", {}), ("lenient", {"screen_threshold": 60})):
        study = study_of(slug=slug, trials_per_participant=2, **options)
        for _ in range(3):
            bot = join(make_bot, study)
            while (trial := bot.participant().current_trial()) is not None:
                reference = trial.items.get(stimulus__role="reference").position
                anchor = trial.items.get(stimulus__role="anchor").position
                bot.trial_page()
                bot.answer(bot.answer_data(trial, scores={reference: 70, anchor: 5}))
        out = tmp_path / slug
        if slug == "strict":
            with pytest.raises(Exception, match="every participant fails the post-screening"):
                call_command("analyze", study=slug, out=str(out), no_audit=True, bootstrap=0,
                             min_time_factor=0.0)
            continue
        call_command("analyze", study=slug, out=str(out), no_audit=True, bootstrap=0,
                     min_time_factor=0.0)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["n_participants"] == 3
        rules = {row["rule"]: row for row in summary["exclusions"]}
        assert rules["Scored the hidden reference below 60 in more than 15% of trials "
                     "(MUSHRA post-screening)"]["participants"] == 0
