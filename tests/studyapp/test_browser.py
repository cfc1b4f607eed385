"""A real Chromium takes the ranking study on the live server."""

import os
from pathlib import Path

import pytest
from playwright.sync_api import expect

from studyapp.survey.models import Participant, Trial, TrialItem
from tests.studyapp.conftest import make_ranking_study

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

ALL_WATCHED = ("() => [...document.querySelectorAll('[data-required] [data-plays]')]"
               ".every(i => +i.value > 0)")


@pytest.fixture(autouse=True)
def _real_watch(settings):
    """The server's own rule: an answer only after the clips' playing time."""
    settings.STUDY_WATCH_TIME_FACTOR = 1.0


@pytest.fixture
def study(transactional_db, media_root, clips):
    return make_ranking_study(clips, completion_url="https://platform.example/complete?cc=OK")


def snap(page, name):
    """Save a screenshot when SURVEY_SCREENSHOTS names a folder, to look at the pages."""
    folder = os.environ.get("SURVEY_SCREENSHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(Path(folder) / f"{name}.png"), full_page=True)


def touch_drag(page, source, target):
    """Drag with a finger: raw touch events through the DevTools protocol."""
    source.scroll_into_view_if_needed()
    target.scroll_into_view_if_needed()
    cdp = page.context.new_cdp_session(page)
    start, end = source.bounding_box(), target.bounding_box()
    x, y = start["x"] + start["width"] / 2, start["y"] + start["height"] / 2
    to_y = end["y"] + end["height"] / 4
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [{"x": x, "y": y}]})
    for k in range(1, 6):
        point = {"x": x, "y": y + (to_y - y) * k / 5}
        cdp.send("Input.dispatchTouchEvent", {"type": "touchMove", "touchPoints": [point]})
    cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
    cdp.detach()


def order(page) -> list[str]:
    """Return the clip tokens of the ranking list, best first."""
    return page.eval_on_selector_all(".rank-row", "rows => rows.map(r => r.dataset.clip)")


def trial_id(page) -> str:
    return page.locator("input[name=trial]").input_value()


def begin(page, url):
    page.goto(url)
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").click()
    expect(page.locator("[data-action]")).to_be_visible()


def wait_until_played(page):
    page.wait_for_function(ALL_WATCHED, timeout=15_000)
    videos = page.eval_on_selector_all(
        "video",
        "vs => vs.map(v => ({played: v.played.length, error: v.error && v.error.code,"
        " duration: v.duration, width: v.videoWidth}))",
    )
    for video in videos:
        assert video["error"] is None and video["played"] > 0
        assert video["width"] == 64 and 0.3 < video["duration"] < 0.5


def test_chromium_completes_the_study(page, live_server, study):
    url = f"{live_server.url}/s/{study.slug}/?PROLIFIC_PID=chrome-1&STUDY_ID=s1&SESSION_ID=x1"
    page.goto(url)
    expect(page.get_by_role("heading", name="Welcome")).to_be_visible()
    expect(page.get_by_text(study.data_note)).to_be_visible()
    snap(page, "desktop-1-welcome")
    page.get_by_role("button", name="Continue").click()
    expect(page.get_by_role("alert")).to_contain_text("tick the box")
    snap(page, "desktop-2-consent-error")
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()
    expect(page.get_by_role("heading", name="Instructions")).to_be_visible()
    snap(page, "desktop-3-instructions")

    # Hold the clips back: until they have played, the answer cannot be sent.
    held = []
    page.route("**/c/*.mp4", lambda route: held.append(route))
    page.get_by_role("button", name="Start").click()
    submit = page.locator("[data-submit]")
    expect(submit).to_be_disabled()
    page.wait_for_selector("[data-trial-form][data-ready]", state="attached")
    snap(page, "desktop-4-trial-loading")
    submit.click(force=True)
    page.evaluate("document.querySelector('[data-trial-form]').requestSubmit()")
    expect(submit).to_be_disabled()
    assert not Trial.objects.filter(answered_at__isnull=False).exists()
    assert held
    page.unroute("**/c/*.mp4")  # the held requests go through now

    answers = {}
    # Trial 1: watched, but unranked: nothing can be sent until the clips are ordered.
    first = trial_id(page)
    wait_until_played(page)
    expect(submit).to_be_disabled()
    expect(page.locator("[data-gate]")).to_contain_text("Answer for every clip")
    assert page.eval_on_selector_all(".rank-select", "ss => ss.map(s => s.value)") == [""] * 3
    before = order(page)
    page.locator(".rank-row").nth(2).drag_to(page.locator(".rank-row").nth(0))
    expect(submit).to_be_enabled()
    after = order(page)
    assert after != before and sorted(after) == sorted(before)
    selects = page.eval_on_selector_all(".rank-select", "ss => ss.map(s => s.value)")
    assert selects == ["1", "2", "3"]
    snap(page, "desktop-5-trial-ranked")
    answers[first] = {token: rank for rank, token in enumerate(after, 1)}
    submit.click()

    # Trial 2: a reload resumes it; then rank with the keyboard and the menus.
    expect(page.locator("input[name=trial]")).not_to_have_value(first)
    second = trial_id(page)
    action = page.locator("[data-action]").inner_text()
    page.reload()
    assert trial_id(page) == second
    assert page.locator("[data-action]").inner_text() == action
    wait_until_played(page)
    before = order(page)
    page.locator(".rank-select").nth(2).select_option("1")
    page.locator(".rank-row").nth(2).get_by_role("button", name="up").focus()
    page.keyboard.press("Enter")
    after = order(page)
    assert after == [before[2], before[1], before[0]]
    answers[second] = {token: rank for rank, token in enumerate(after, 1)}
    page.get_by_role("button", name="Submit ranking").click()

    code = page.locator("[data-completion-code]")
    snap(page, "desktop-6-done")
    expect(code).to_have_text(Participant.objects.get().completion_code)
    expect(page.get_by_role("link", name="Return to the study platform")).to_have_attribute(
        "href", "https://platform.example/complete?cc=OK"
    )

    participant = Participant.objects.get()
    ids = {"PROLIFIC_PID": "chrome-1", "STUDY_ID": "s1", "SESSION_ID": "x1"}
    assert participant.external_ids == ids
    stored = {
        str(trial.pk): {item.token: item.answers["preference"] for item in trial.items.all()}
        for trial in participant.trials.all()
    }
    assert stored == answers
    assert not TrialItem.objects.filter(plays=0).exists()
    assert not TrialItem.objects.filter(fetched_at=None).exists()  # the server saw them fetched
    assert all(t.time_ms > 400 for t in participant.trials.all())
    events = participant.trials.order_by("index").first().events
    assert {"play", "ended"} <= {name for _, name, _ in events}  # the page's log is kept


def submit_and_wait(page):
    current = trial_id(page)
    page.locator("[data-submit]").click()
    page.wait_for_function(
        "id => (document.querySelector('input[name=trial]') || {}).value !== id", arg=current
    )


def test_a_phone_sized_screen_fits_and_ranks_by_touch_and_menus(phone_page, live_server, study):
    page = phone_page
    page.goto(f"{live_server.url}/s/{study.slug}/")
    snap(page, "phone-1-welcome")
    begin(page, f"{live_server.url}/s/{study.slug}/")
    snap(page, "phone-2-trial-loading")
    wait_until_played(page)
    assert page.evaluate("document.documentElement.scrollWidth") <= 390
    expect(page.locator("[data-submit]")).to_be_in_viewport()
    rows = page.locator(".rank-row")
    touch_drag(page, rows.nth(2).locator(".grip"), rows.nth(0))
    snap(page, "phone-3-trial-ranked")
    submit_and_wait(page)
    wait_until_played(page)
    page.get_by_role("button", name="Keep this order").click()
    page.locator(".rank-select").nth(1).select_option("3")
    submit_and_wait(page)
    expect(page.locator("[data-completion-code]")).to_be_visible()
    snap(page, "phone-4-done")
    ranks = [
        [a["preference"] for a in trial.items.order_by("position").values_list("answers", flat=True)]
        for trial in Trial.objects.order_by("index")
    ]
    assert ranks == [[2, 3, 1], [1, 3, 2]]
