"""The first path end to end: the demo's configs (demo data, the shipped a2m and cond_gru
checkpoints) through the one build → a served ranking study taken in Chromium → export
→ analysis, which count exactly the submitted ranks; and the demo's one study of every
type, each finished by simulated participants."""

import json
from io import StringIO
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from django.core.management import call_command
from playwright.sync_api import expect

from rendering import list_styles
from studyapp.stimuli.management.commands.demo import DEMO_CONFIGS, demo_configs
from studyapp.survey.models import Participant, ScoringStandard, Stimulus, TrialItem
from studyapp.stimuli.build import build_stimuli
from studyapp.stimuli.config import load_config
from studyapp.survey.study_types import list_study_types

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.django_db(transaction=True)]

ACTIONS = ["walk", "jump", "wave"]
SMALL = ["clips_per_source=1", "render.size=96"]
PLAIN = ["study.practice=false", "study.catch_trials=0", "study.repeat_trials=0",
         "study.ask_demographics=false"]


def build(name, tmp_path, *overrides):
    path = name if isinstance(name, Path) else DEMO_CONFIGS / name
    config = load_config(path, [*SMALL, *overrides])
    return build_stimuli(config, tmp_path / config.slug, cache=tmp_path / "cache")


@pytest.fixture
def demo_study(transactional_db, media_root, tmp_path):
    actions = f"actions=[{','.join(ACTIONS)}]"
    return build("ranking.yaml", tmp_path, actions, "slug=e2e-ranking", *PLAIN).study


def test_built_study_holds_real_and_generated_clips(demo_study):
    stimuli = Stimulus.objects.filter(study=demo_study)
    assert sorted({s.source for s in stimuli}) == ["a2m", "cond_gru", "real"]
    assert sorted({s.action for s in stimuli}) == sorted(ACTIONS)
    assert stimuli.count() == 3 * len(ACTIONS)
    assert demo_study.clips_per_trial == 3
    assert "synthetic" in demo_study.data_note


def test_rebuilding_the_same_config_changes_nothing(demo_study, tmp_path):
    actions = f"actions=[{','.join(ACTIONS)}]"
    again = build("ranking.yaml", tmp_path, actions, "slug=e2e-ranking", *PLAIN)
    assert again.study.pk == demo_study.pk and again.unchanged and again.rendered == 0
    assert again.sampled == []
    assert Stimulus.objects.filter(study=again.study).count() == 3 * len(ACTIONS)


def test_browser_answers_are_exported_and_analysed_exactly(demo_study, page, live_server, tmp_path):
    rng = np.random.default_rng(7)
    submitted = {}  # (crowd id, item token) -> rank
    for person in ("e2e-0", "e2e-1"):
        page.context.clear_cookies()
        page.goto(f"{live_server.url}/s/{demo_study.slug}/?PROLIFIC_PID={person}")
        page.get_by_label("I have read the information above").check()
        page.get_by_role("button", name="Continue").click()
        page.get_by_role("button", name="Start").click()
        for _ in ACTIONS:
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

    items = TrialItem.objects.select_related("stimulus", "trial__participant")
    stored = {(item.trial.participant.external_ids["PROLIFIC_PID"], item.token):
              item.answers["preference"] for item in items}
    assert stored == submitted
    stimulus_of = {item.token: item.stimulus.token for item in items}

    csv = tmp_path / "responses.csv"
    call_command("export_responses", study=demo_study.slug, out=str(csv))
    table = pd.read_csv(csv)
    assert len(table) == len(submitted) == 2 * 3 * len(ACTIONS)
    exported = sorted(zip(table["PROLIFIC_PID"], table["stimulus_token"], table["rank"]))
    assert exported == sorted((pid, stimulus_of[token], rank)
                              for (pid, token), rank in submitted.items())

    out = tmp_path / "analysis"
    call_command("analyze", study=demo_study.slug, out=str(out))
    shares = pd.read_csv(out / "rank_shares.csv", index_col="source")
    sources = {item.token: item.stimulus.source for item in items}
    for source in ("real", "a2m", "cond_gru"):
        ranks = [rank for (_, token), rank in submitted.items() if sources[token] == source]
        assert shares.loc[source, "n_judgements"] == len(ranks)
        for rank in (1, 2, 3):
            assert shares.loc[source, f"rank_{rank}"] == pytest.approx(ranks.count(rank) / len(ranks))
    assert (out / "rank_shares.png").stat().st_size > 1000


def test_the_demo_has_a_study_of_every_type_that_bots_can_finish(
    transactional_db, media_root, tmp_path, live_server
):
    studies = [build(path, tmp_path, *fixed, "actions=[walk,wave]",
                     "study.trials_per_participant=null").study for path, fixed in demo_configs()]
    assert sorted(s.study_type for s in studies) == list_study_types()  # one of every type
    by_type = {s.study_type: s for s in studies}
    for study in studies:
        judged = Stimulus.objects.judged().filter(study=study)
        assert sorted({s.source for s in judged}) == ["a2m", "cond_gru", "real"]
        # Two broken versions of a clip of each source, per action.
        assert study.stimuli.filter(role="catch").count() == 2 * 3 * 2
        assert study.stimuli.filter(role="practice").exists()
        assert study.practice and study.catch_trials == 1 and study.ask_demographics
    standards = ScoringStandard.objects.filter(study=by_type["rating_standards"])
    assert standards.count() == 10 and all(s.stimulus.role == "example" for s in standards)
    assert by_type["rating_reference"].stimuli.filter(role="reference", source="real").count() == 2
    if "mesh" in list_styles():  # fake or real is shown as a body, not a stick figure
        mesh = set(by_type["fake_or_real"].stimuli.values_list("video_hash", flat=True))
        assert not mesh & set(by_type["ranking"].stimuli.values_list("video_hash", flat=True))
    # Studies of the same sources share their clips: rendered once, into one cache.
    stick = set(by_type["ranking"].stimuli.judged().values_list("video_hash", flat=True))
    assert stick == set(by_type["pairwise"].stimuli.judged().values_list("video_hash", flat=True))

    for study in studies:
        call_command("simulate_participants", study=study.slug, n=1, url=live_server.url,
                     policy="prefer-real", seed=0, pace=0, stdout=StringIO())
    assert Participant.objects.filter(completed_at__isnull=False).count() == len(studies)
    out = StringIO()
    call_command("studies", json=True, stdout=out)
    listed = {row["slug"]: row for row in json.loads(out.getvalue())}
    assert all(listed[s.slug]["completed"] == 1 for s in studies)
    assert sum(row["excluded"] for row in listed.values()) == 0  # prefer-real spots the catch


@pytest.mark.django_db(transaction=True)
def test_demo_command_builds_prints_links_and_reuses_the_build(settings, tmp_path, media_root):
    settings.VAR_DIR = tmp_path / "var"
    small = {"no_serve": True, "size": 64, "actions": "walk,wave", "clips_per_source": 1}
    first = StringIO()
    call_command("demo", stdout=first, **small)
    text = first.getvalue()
    for study_type in list_study_types():
        assert study_type in text
    assert "/s/demo-ranking/" in text and "/admin/" in text and "password" in text
    second = StringIO()
    call_command("demo", stdout=second, **small)
    lines = [line for line in second.getvalue().splitlines() if " clips, " in line]
    assert len(lines) == len(list_study_types())
    assert all("0 rendered now, unchanged" in line for line in lines)
