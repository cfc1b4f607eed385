"""A real Chromium takes a graded pairwise study on the live server, on a desktop by
keyboard and mouse and on a phone by touch: the 7-point scale and "Both bad" are all on
screen, the play gate holds, every answer is stored as given and the catch is graded."""

import pytest
from playwright.sync_api import expect

from studyapp.survey.models import Participant, Trial
from studyapp.survey.study_types.pairwise_graded import SCALE
from tests.studyapp.conftest import make_study
from tests.studyapp.test_browser import ALL_WATCHED, snap, trial_id
from tests.studyapp.test_browser_types import FORM_DATA, begin, submit_and_wait

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

LABELS = [text for _, text, _ in SCALE] + ["Both bad"]
VALUES = [value for value, _, _ in SCALE]


@pytest.fixture
def graded_study(transactional_db, media_root, clips, extra_clips):
    def make(**fields):
        fields = {"practice": True, "ask_demographics": True, "trials_per_participant": 3} | fields
        return make_study("pairwise_graded", clips, extra_clips, catch=True, **fields)

    return make


def intact_better(trial: Trial) -> str:
    """Return the answer that judges the clip that is not broken better (as a person who
    spots the broken clip would), read from the database."""
    broken = trial.items.get(stimulus__role="catch").position
    return "right" if broken == 0 else "left"


def scale_fits(page, width: int) -> None:
    """Every answer of the scale is inside the page's width, its words inside its button."""
    for label in LABELS:
        box = page.locator(".choice", has_text=label).first.bounding_box()
        assert box and box["x"] >= 0 and box["x"] + box["width"] <= width + 0.5, label
    assert page.evaluate("document.documentElement.scrollWidth") <= width
    overflowing = page.eval_on_selector_all(
        "[data-graded] .choice span:first-of-type",
        "spans => spans.filter(s => s.scrollWidth > s.clientWidth + 1).map(s => s.textContent)")
    assert not overflowing  # every label fits inside its button


def choose(page, value: str, how: str) -> None:
    option = page.locator(f".choice-{value}")
    if how == "key":
        page.evaluate("document.activeElement && document.activeElement.blur()")
        page.keyboard.press(str(VALUES.index(value) + 1))
    elif how == "tap":
        option.tap()
    else:
        option.click()
    expect(option.locator("input")).to_be_checked()


def finish(page, plan, how, name) -> dict:
    """Answer every trial left (main trials from ``plan`` in turn, a catch trial as a
    person who spots the broken clip); return ``{trial id: answer}``."""
    answers, n = {}, 0
    while "/trial/" in page.url:
        page.wait_for_function(ALL_WATCHED, timeout=15_000)
        current = trial_id(page)
        trial = Trial.objects.get(pk=current)
        value = intact_better(trial) if trial.kind == "catch" else plan[n % len(plan)]
        choose(page, value, "click" if value == "both_bad" and how == "key" else how)
        answers[current] = value
        if n == 0:
            snap(page, f"{name}-trial")
        submit_and_wait(page)
        n += 1
    return answers


def test_chromium_completes_a_graded_study_by_keyboard_and_mouse(page, live_server, graded_study):
    study = graded_study()
    page.goto(f"{live_server.url}/s/{study.slug}/?PROLIFIC_PID=chrome-graded")
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()
    expect(page.get_by_text('"Both bad"').first).to_be_visible()

    # Hold the clips back: an answer chosen cannot be sent yet, nor forged.
    held = []
    page.route("**/c/*.mp4", lambda route: held.append(route))
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("[data-trial-form][data-ready]", state="attached")
    expect(page.locator(".notice")).to_contain_text("Practice question")
    scale_fits(page, 1280)
    choose(page, "left_slightly", "key")
    submit = page.locator("[data-submit]")
    expect(submit).to_be_disabled()
    data = page.evaluate(FORM_DATA)
    assert data["choice"] == "left_slightly"
    forged = {k: "0" if k.startswith("plays_") else v for k, v in data.items()}
    refused = page.request.post(page.url, form=forged)
    assert refused.status == 400 and "has not been played to the end yet" in refused.text()
    assert held and not Trial.objects.filter(answered_at__isnull=False).exists()
    page.unroute("**/c/*.mp4")
    page.reload()

    answers = finish(page, ["left_much", "no_preference", "right", "both_bad"], "key",
                     "desktop-pairwise_graded")
    expect(page.get_by_role("heading", name="Almost done")).to_be_visible()
    page.get_by_label("Age").select_option("25-34")
    page.get_by_role("button", name="Finish").click()
    participant = Participant.objects.get()
    expect(page.locator("[data-completion-code]")).to_have_text(participant.completion_code)

    trials = {str(t.pk): t for t in participant.trials.all()}
    assert set(answers) == set(trials)
    assert sorted(t.kind for t in trials.values()) == ["catch", "main", "main", "main", "practice"]
    for key, given in answers.items():
        stored = trials[key].answers.get("preference")
        assert stored == (None if trials[key].kind == "practice" else given)
    catch = next(t for t in trials.values() if t.kind == "catch")
    assert catch.catch_passed is True


def test_a_phone_takes_a_graded_study_by_touch(phone_page, live_server, graded_study):
    page = phone_page
    study = graded_study(practice=False, ask_demographics=False)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    page.get_by_role("button", name="Start").click()
    page.wait_for_function(ALL_WATCHED, timeout=15_000)
    scale_fits(page, 390)
    # On a phone the scale is a column, A's end on top: every answer is a full-width button.
    tops = [page.locator(f".choice-{v}").bounding_box()["y"] for v in VALUES]
    assert tops == sorted(tops) and len(set(tops)) == len(tops)
    for value in VALUES:
        assert page.locator(f".choice-{value}").bounding_box()["height"] >= 40  # a finger's size
    expect(page.locator("[data-submit]")).to_be_in_viewport()
    answers = finish(page, ["right_much", "left_slightly", "both_bad"], "tap", "phone-pairwise_graded")
    expect(page.locator("[data-completion-code]")).to_be_visible()
    trials = {str(t.pk): t for t in Trial.objects.all()}
    assert {key: trials[key].answers.get("preference") for key in answers} == answers
    assert next(t for t in trials.values() if t.kind == "catch").catch_passed is True
