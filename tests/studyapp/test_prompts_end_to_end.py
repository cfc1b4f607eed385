"""A prompts study end to end: two models' MDM results.npy → build_stimuli with the
studies/mdm_pairwise.yaml preset → the pairwise study taken in Chromium (desktop and
phone), its trial pages showing the prompts (escaped, wrapped) and never the source →
the export's prompt column → the analysis per prompt."""

import json
from pathlib import Path

import pandas as pd
import pytest
from django.core.files.storage import default_storage
from django.core.management import call_command
from playwright.sync_api import expect

from studyapp.survey.models import Participant, Stimulus, Trial
from studyapp.stimuli.build import build_stimuli
from studyapp.stimuli.config import load_config
from tests.studyapp.mdm_results import write_mdm_results

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.django_db(transaction=True)]

ROOT = Path(__file__).resolve().parents[2]
LONG = ("a person walks forward slowly, stops, looks over the left shoulder, turns around "
        "completely and then walks back to where they started while waving both arms above "
        "their head")
PROMPTS = ["a person jumps <b>twice</b> & lands", "someone waves with the right hand",
           "a man sits down on a chair", LONG]
SOURCES = ("model_a", "model_b")


@pytest.fixture
def prompt_study(transactional_db, media_root, tmp_path):
    # model_b wrote the same prompts in another order, capitalised, with full stops.
    write_mdm_results(tmp_path / "model_a" / "results.npy", PROMPTS, repetitions=2, seed=1)
    other = [p[0].upper() + p[1:] + "." for p in PROMPTS][::-1]
    write_mdm_results(tmp_path / "model_b" / "results.npy", other, repetitions=3, seed=2)
    overrides = [
        f"sources.0.file={tmp_path / 'model_a' / 'results.npy'}",
        f"sources.1.file={tmp_path / 'model_b' / 'results.npy'}",
        "prompts_from=null", f"prompts={json.dumps(PROMPTS)}",
        "frames=20", "render.size=64", "slug=e2e-prompts",
        "study.repeat_trials=0", "study.ask_demographics=false",
    ]
    config = load_config(ROOT / "studies" / "mdm_pairwise.yaml", overrides)
    return build_stimuli(config, tmp_path / "build", cache=tmp_path / "cache").study


def test_the_build_holds_every_sources_clip_of_every_prompt_blind(prompt_study):
    judged = Stimulus.objects.judged().filter(study=prompt_study)
    assert sorted((s.source, s.prompt) for s in judged) == sorted(
        (source, prompt) for source in SOURCES for prompt in PROMPTS)
    catch = prompt_study.stimuli.filter(role="catch")  # two of each source's, per prompt
    assert sorted(catch.values_list("prompt", flat=True)) == sorted(PROMPTS * 4)
    # Files tell nothing: content-hash names and one size for every clip of the study.
    stimuli = list(prompt_study.stimuli.all())
    assert len({default_storage.size(s.video) for s in stimuli}) == 1
    assert len({s.duration for s in stimuli}) == 1
    assert not any(source in s.video for s in stimuli for source in SOURCES)


def answer_trials(page, study, person, seen):
    """Take every trial of the page's participant: check the prompt shown, choose the
    intact clip of a catch trial and the left clip otherwise."""
    while True:
        trial_head = page.locator("[data-prompt], [data-completion-code]").first
        expect(trial_head).to_be_visible()
        if page.locator("[data-completion-code]").count():
            return
        prompt = page.locator("[data-prompt]")
        shown = prompt.evaluate("el => el.textContent")
        assert shown in PROMPTS
        assert prompt.evaluate("el => el.children.length") == 0  # escaped, not markup
        html = page.content()
        assert "<b>twice</b>" not in html
        for source in SOURCES:
            assert source not in html
        box = prompt.bounding_box()
        width = page.viewport_size["width"]
        assert box["x"] >= 0 and box["x"] + box["width"] <= width
        assert page.evaluate("() => document.documentElement.scrollWidth") <= width
        if shown == LONG:
            assert box["height"] > 2 * prompt.evaluate(
                "el => parseFloat(getComputedStyle(el).lineHeight)") - 1  # wrapped
        participant = Participant.objects.get(study=study, external_ids__PROLIFIC_PID=person)
        trial = participant.current_trial()
        assert trial.prompt == shown
        seen[(person, trial.index)] = shown
        page.wait_for_function(
            "() => [...document.querySelectorAll('[data-plays]')].every(i => +i.value > 0)",
            timeout=20_000)
        items = {item.position: item.stimulus for item in trial.items.all()}
        side = "right" if trial.kind == Trial.Kind.CATCH and items[0].is_catch else "left"
        page.locator(f"label.choice-{side}").click()
        with page.expect_navigation():
            page.get_by_role("button", name="Submit choice").click()


def take_part(page, url, study, person, seen):
    page.context.clear_cookies()
    page.goto(f"{url}/s/{study.slug}/?PROLIFIC_PID={person}")
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()
    expect(page.get_by_text("matches the text better")).to_be_visible()
    page.get_by_role("button", name="Start").click()
    answer_trials(page, study, person, seen)


def test_prompts_are_shown_answered_exported_and_analysed(prompt_study, page, phone_page,
                                                           live_server, tmp_path):
    seen = {}
    take_part(page, live_server.url, prompt_study, "desk-1", seen)
    take_part(phone_page, live_server.url, prompt_study, "phone-1", seen)
    for person in ("desk-1", "phone-1"):
        shown = [p for (who, _), p in seen.items() if who == person]
        assert len(shown) == len(PROMPTS) + 1  # every prompt once, and a catch trial
        assert set(shown) == set(PROMPTS)
        assert Participant.objects.get(external_ids__PROLIFIC_PID=person).outcome == "completed"

    csv = tmp_path / "responses.csv"
    call_command("export_responses", study=prompt_study.slug, out=str(csv))
    table = pd.read_csv(csv)
    assert "prompt" in table.columns
    exported = {(row.PROLIFIC_PID, int(row.trial)): row.prompt for row in table.itertuples()}
    assert exported == seen
    main = table.loc[table["trial_kind"] == "main"]
    assert sorted(main["prompt"].unique()) == sorted(PROMPTS)
    assert sorted(main["source"].unique()) == list(SOURCES)

    out = tmp_path / "analysis"
    call_command("analyze", study=prompt_study.slug, out=str(out), no_audit=True)
    by_prompt = pd.read_csv(out / "by_prompt.csv")
    assert sorted(by_prompt["prompt"].unique()) == sorted(PROMPTS)
    assert set(by_prompt["source"]) == set(SOURCES)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_judgements"] == 2 * 2 * len(PROMPTS)


def test_the_blindness_audit_cannot_tell_the_two_models_apart(prompt_study, live_server,
                                                               tmp_path):
    out = tmp_path / "audit.json"
    call_command("audit_blindness", study=prompt_study.slug, url=live_server.url,
                 json_out=str(out))
    result = json.loads(out.read_text())  # the deep audit: every family, two deliveries
    source = result["source: delivery"]
    assert source["n"] == 2 * len(PROMPTS)  # model_a against model_b
    assert source["auc"] is not None and source["passed"]
    assert result["catch: delivery"]["n"] == (2 + 4) * len(PROMPTS)
    assert all(part["passed"] for part in result.values()), result
