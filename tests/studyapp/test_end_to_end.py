"""The first path end to end: demo data → a2m and cond_gru → clips → a served ranking
study taken in Chromium → export → analysis, which count exactly the submitted ranks;
and the demo's one study of every type, each finished by simulated participants."""

import json
from io import StringIO

import numpy as np
import pandas as pd
import pytest
from django.core.management import call_command
from playwright.sync_api import expect

from rendering import list_styles
from studyapp.survey.demo import STUDY_TYPES, DemoPlan, build_demo, demo_studies
from studyapp.survey.models import Participant, ScoringStandard, Stimulus, TrialItem

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.django_db(transaction=True)]

PLAN = DemoPlan(actions=["walk", "jump", "wave"], preset="tiny", iters=4, clips_per_source=1,
                size=96, slug="e2e-ranking", study_types=("ranking",), checks=False)


@pytest.fixture
def demo_study(transactional_db, media_root, tmp_path):
    return build_demo(PLAN, tmp_path / "demo", log=lambda *_: None)


def test_built_study_holds_real_and_generated_clips(demo_study):
    stimuli = Stimulus.objects.filter(study=demo_study)
    assert sorted({s.source for s in stimuli}) == ["a2m", "cond_gru", "real"]
    assert sorted({s.action for s in stimuli}) == sorted(PLAN.actions)
    assert stimuli.count() == 3 * len(PLAN.actions)
    assert demo_study.clips_per_trial == 3
    assert "synthetic" in demo_study.data_note


def test_rebuilding_the_same_plan_reuses_the_study(demo_study, tmp_path):
    again = build_demo(PLAN, tmp_path / "demo", log=lambda *_: None)
    assert again.pk == demo_study.pk
    assert Stimulus.objects.filter(study=again).count() == 3 * len(PLAN.actions)


def test_browser_answers_are_exported_and_analysed_exactly(demo_study, page, live_server, tmp_path):
    rng = np.random.default_rng(7)
    submitted = {}  # (crowd id, stimulus token) -> rank
    for person in ("e2e-0", "e2e-1"):
        page.context.clear_cookies()
        page.goto(f"{live_server.url}/s/{demo_study.slug}/?PROLIFIC_PID={person}")
        page.get_by_label("I have read the information above").check()
        page.get_by_role("button", name="Continue").click()
        page.get_by_role("button", name="Start").click()
        for _ in PLAN.actions:
            expect(page.locator("[data-action]")).to_be_visible()
            page.wait_for_function(
                "() => [...document.querySelectorAll('[data-plays]')].every(i => +i.value > 0)",
                timeout=20_000,
            )
            wanted = rng.permutation(3) + 1  # ranks for the rows as first shown
            tokens = page.eval_on_selector_all(".rank-row", "rows => rows.map(r => r.dataset.clip)")
            for token, rank in sorted(zip(tokens, wanted), key=lambda pair: pair[1]):
                row = page.locator(f'.rank-row[data-clip="{token}"]')
                row.locator(".rank-select").select_option(str(rank))
            final = page.eval_on_selector_all(".rank-row", "rows => rows.map(r => r.dataset.clip)")
            submitted.update({(person, token): rank for rank, token in enumerate(final, 1)})
            page.get_by_role("button", name="Submit ranking").click()
        expect(page.locator("[data-completion-code]")).to_be_visible()

    stored = {
        (item.trial.participant.external_ids["PROLIFIC_PID"], item.stimulus.token): item.rank
        for item in TrialItem.objects.select_related("stimulus", "trial__participant")
    }
    assert stored == submitted

    csv = tmp_path / "responses.csv"
    call_command("export_responses", study=demo_study.slug, out=str(csv))
    table = pd.read_csv(csv)
    assert len(table) == len(submitted) == 2 * 3 * len(PLAN.actions)
    exported = zip(table["PROLIFIC_PID"], table["stimulus_token"], table["rank"])
    assert {(pid, token): rank for pid, token, rank in exported} == submitted

    out = tmp_path / "analysis"
    call_command("analyze", study=demo_study.slug, out=str(out))
    shares = pd.read_csv(out / "rank_shares.csv", index_col="source")
    sources = {s.token: s.source for s in Stimulus.objects.filter(study=demo_study)}
    for source in ("real", "a2m", "cond_gru"):
        ranks = [rank for (_, token), rank in submitted.items() if sources[token] == source]
        assert shares.loc[source, "n_judgements"] == len(ranks)
        for rank in (1, 2, 3):
            assert shares.loc[source, f"rank_{rank}"] == pytest.approx(ranks.count(rank) / len(ranks))
    assert (out / "rank_shares.png").stat().st_size > 1000


EVERY_TYPE = DemoPlan(actions=["walk", "wave"], preset="tiny", iters=2, clips_per_source=1,
                      size=96, slug="all-ranking", fake_or_real_trials=3)


def test_the_demo_has_a_study_of_every_type_that_bots_can_finish(
    transactional_db, media_root, tmp_path, live_server
):
    first = build_demo(EVERY_TYPE, tmp_path / "demo", log=lambda *_: None)
    studies = demo_studies(EVERY_TYPE)
    assert [s.study_type for s in studies] == list(STUDY_TYPES) and first == studies[0]
    assert [s.slug for s in studies][1:] == [
        "all-fake-or-real", "all-rating-standards", "all-rating-reference", "all-pairwise"
    ]
    by_type = {s.study_type: s for s in studies}
    for study in studies:
        judged = Stimulus.objects.judged().filter(study=study)
        assert sorted({s.source for s in judged}) == ["a2m", "cond_gru", "real"]
        assert study.stimuli.filter(is_catch=True).count() == 2  # one per action
        assert study.practice and study.catch_trials == 1 and study.ask_demographics
    standards = ScoringStandard.objects.filter(study=by_type["rating_standards"])
    assert standards.count() == 10 and all(s.stimulus.is_standard_example for s in standards)
    assert by_type["rating_reference"].stimuli.filter(is_reference=True, source="real").count() == 2
    if "mesh" in list_styles():  # fake or real is shown as a body, not a stick figure
        mesh = set(by_type["fake_or_real"].stimuli.values_list("video_hash", flat=True))
        assert not mesh & set(by_type["ranking"].stimuli.values_list("video_hash", flat=True))

    for study in studies:
        call_command("simulate_participants", study=study.slug, n=1, url=live_server.url,
                     policy="prefer-real", seed=0, pace=0, stdout=StringIO())
    assert Participant.objects.filter(completed_at__isnull=False).count() == len(STUDY_TYPES)
    out = StringIO()
    call_command("studies", json=True, stdout=out)
    listed = {row["slug"]: row for row in json.loads(out.getvalue())}
    assert all(listed[s.slug]["completed"] == 1 for s in studies)
    assert sum(row["excluded"] for row in listed.values()) == 0  # prefer-real spots the catch


@pytest.mark.django_db(transaction=True)
def test_demo_command_builds_prints_links_and_reuses_the_build(settings, tmp_path, media_root):
    from io import StringIO

    settings.VAR_DIR = tmp_path / "var"
    small = {"no_serve": True, "iters": 2, "size": 64, "actions": "walk,wave", "clips_per_source": 1}
    first = StringIO()
    call_command("demo", stdout=first, **small)
    text = first.getvalue()
    for study_type in ("ranking", "fake_or_real", "rating_standards", "rating_reference", "pairwise"):
        assert study_type in text
    assert "/s/demo-ranking/" in text and "/admin/" in text and "password" in text
    second = StringIO()
    call_command("demo", stdout=second, **small)
    assert "reusing" in second.getvalue()
