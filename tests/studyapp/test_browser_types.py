"""A real Chromium takes a study of every other type on the live server (ranking has
its own tests in test_browser): practice, the play gate on client and server, resume
after a reload, keyboard and touch answers, closing questions, completion."""

import pytest
from playwright.sync_api import expect

from studyapp.survey.models import Participant, Trial
from tests.studyapp.conftest import make_study
from tests.studyapp.test_browser import ALL_WATCHED, snap, trial_id

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

TYPES = ["fake_or_real", "rating_standards", "rating_reference", "pairwise", "best_of_k",
         "mushra"]
FORM_DATA = "() => Object.fromEntries(new FormData(document.querySelector('[data-trial-form]')))"


@pytest.fixture
def study_of(transactional_db, media_root, clips, extra_clips):
    def make(study_type, **fields):
        fields = {"practice": True, "ask_demographics": True, "trials_per_participant": 2} | fields
        return make_study(study_type, clips, extra_clips, catch=True, **fields)

    return make


def begin(page, url):
    page.goto(url)
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()


def tokens(page) -> list[str]:
    """Return the judged clips of the trial on screen, in screen order."""
    return page.eval_on_selector_all(
        "[data-clip-card][data-role=judged] input[name^=plays_]",
        "inputs => inputs.map(i => i.name.slice(6))",
    )


def answer(page, study_type: str, n: int, tap=False) -> dict:
    """Answer the trial on screen as a person would; return what was answered."""
    clips = tokens(page)
    page.evaluate("document.activeElement && document.activeElement.blur()")
    if study_type == "fake_or_real":
        page.keyboard.press("g")  # the broken clip is "generated"; so is everything else
        return dict.fromkeys(clips, False)
    if study_type == "pairwise":
        side = "left" if n % 2 else "right"
        if tap:
            page.locator(f".choice-{side}").tap()
        else:
            page.keyboard.press("ArrowLeft" if side == "left" else "ArrowRight")
        return {"choice": side}
    if study_type == "best_of_k":  # a clip on even trials, "All bad" on odd ones
        if n % 2:
            target, given = page.locator(".choice-all_bad"), "all_bad"
        else:
            target, given = page.locator(".judged").nth(n % len(clips)).locator(".choice"), n % len(clips)
        target.tap() if tap else target.click()
        return {"pick": given}
    if study_type == "mushra":  # drag (or tap) every slider; the last one unlocks the answer
        scores = {}
        for i, token in enumerate(clips):
            if i == len(clips) - 1:
                expect(page.locator("[data-submit]")).to_be_disabled()  # one slider untouched
            box = page.locator(".judged").nth(i)
            slider, number = box.locator("input[type=range]"), box.locator("input[type=number]")
            if tap:
                slider.tap()
            else:
                slider.fill(str(10 * (1 + (i + n) % 4)))  # 10-40: the broken clip scores low
            scores[token] = int(number.input_value())
        return scores
    scores = {}
    for i, token in enumerate(clips):
        scores[token] = 1 + (i + n) % 2  # 1 or 2: the broken clip, wherever, scores low
        card = page.locator(".judged").nth(i)
        choice = card.locator(".choice").nth(scores[token] - 1)
        choice.tap() if tap else choice.click()
    return scores


def submit_and_wait(page):
    current = trial_id(page)
    page.locator("[data-submit]").click()
    page.wait_for_function(
        "id => (document.querySelector('input[name=trial]') || {}).value !== id", arg=current
    )


def stored(trial: Trial, study_type: str) -> dict:
    key = trial.participant.study.kind.criteria(trial.participant.study)[0].key
    if study_type == "pairwise":
        return {"choice": trial.answers.get(key)}
    if study_type == "best_of_k":
        return {"pick": trial.answers.get(key)}
    return {item.token: item.answers.get(key) for item in trial.items.judged()}


def finish(page, study_type, start=0, tap=False, name="") -> dict:
    """Answer every trial left; return ``{trial id: answer}``."""
    answers, n = {}, start
    while "/trial/" in page.url:
        page.wait_for_function(ALL_WATCHED, timeout=15_000)
        current = trial_id(page)
        answers[current] = answer(page, study_type, n, tap)
        if n == start and name:
            snap(page, f"{name}-trial")
        submit_and_wait(page)
        n += 1
    return answers


@pytest.mark.parametrize("study_type", TYPES)
def test_chromium_completes_every_type(page, live_server, study_of, study_type):
    study = study_of(study_type)
    begin(page, f"{live_server.url}/s/{study.slug}/?PROLIFIC_PID=chrome-{study_type}")
    snap(page, f"desktop-{study_type}-instructions")

    # Hold the clips back: whatever is chosen, the answer cannot be sent yet.
    held = []
    page.route("**/c/*.mp4", lambda route: held.append(route))
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("[data-trial-form][data-ready]", state="attached")
    expect(page.locator(".notice")).to_contain_text("Practice question")
    answer(page, study_type, 0)
    submit = page.locator("[data-submit]")
    expect(submit).to_be_disabled()
    page.evaluate("document.querySelector('[data-trial-form]').requestSubmit()")
    expect(submit).to_be_disabled()
    data = page.evaluate(FORM_DATA)
    forged = {k: "0" if k.startswith("plays_") else v for k, v in data.items()}
    refused = page.request.post(page.url, form=forged)
    assert refused.status == 400 and "has not been played to the end yet" in refused.text()
    assert held and not Trial.objects.filter(answered_at__isnull=False).exists()
    page.unroute("**/c/*.mp4")

    # A reload resumes the same trial; then every trial is answered.
    first = trial_id(page)
    page.reload()
    assert trial_id(page) == first
    answers = finish(page, study_type, name=f"desktop-{study_type}")

    expect(page.get_by_role("heading", name="Almost done")).to_be_visible()
    snap(page, f"desktop-{study_type}-about-you")
    page.get_by_label("Age").select_option("25-34")
    page.get_by_role("button", name="Finish").click()
    participant = Participant.objects.get()
    expect(page.locator("[data-completion-code]")).to_have_text(participant.completion_code)
    snap(page, f"desktop-{study_type}-done")

    assert participant.demographics["age_range"] == "25-34"
    trials = {str(t.pk): t for t in participant.trials.all()}
    assert set(answers) == set(trials)
    kinds = sorted(t.kind for t in trials.values())
    assert kinds == ["catch", "main", "main", "practice"]
    for key, given in answers.items():
        trial = trials[key]
        assert trial.time_ms > 0 and all(item.plays >= 1 for item in trial.items.filter(required=True))
        assert not trial.items.filter(required=True, fetched_at=None).exists()
        if trial.kind == "practice":
            assert set(stored(trial, study_type).values()) == {None}
        else:
            assert stored(trial, study_type) == given
    catch = next(t for t in trials.values() if t.kind == "catch")
    assert catch.catch_passed is not None
    if study_type not in ("pairwise", "best_of_k"):
        assert catch.catch_passed  # every clip was called generated or scored 1-2


@pytest.mark.parametrize("study_type", ["pairwise", "rating_reference", "best_of_k", "mushra"])
def test_a_phone_takes_the_study_by_touch(phone_page, live_server, study_of, study_type):
    page = phone_page
    study = study_of(study_type, practice=False, ask_demographics=False)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    page.get_by_role("button", name="Start").click()
    page.wait_for_function(ALL_WATCHED, timeout=15_000)
    assert page.evaluate("document.documentElement.scrollWidth") <= 390
    expect(page.locator("[data-submit]")).to_be_in_viewport()
    answers = finish(page, study_type, tap=True, name=f"phone-{study_type}")
    expect(page.locator("[data-completion-code]")).to_be_visible()
    snap(page, f"phone-{study_type}-done")
    trials = {str(t.pk): t for t in Trial.objects.all()}
    assert {key: stored(trials[key], study_type) for key in answers} == answers
