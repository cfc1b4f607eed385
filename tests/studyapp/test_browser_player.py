"""A study played in the page (render.player: webgl) in a real Chromium, on desktop and
phone viewports: the canvas draws the figure and its frames advance, the answer unlocks
once every clip has looped, the server saw the payloads fetched and stores the answer;
without WebGL 2 the same page plays the mp4s."""

import pytest
from playwright.sync_api import expect

from studyapp.stimuli.management.commands.demo import DEMO_CONFIGS
from studyapp.survey.models import Participant, TrialItem
from studyapp.stimuli.build import build_stimuli
from studyapp.stimuli.config import load_config
from tests.studyapp.test_browser import ALL_WATCHED
from tests.studyapp.test_motion_player import FIGURE_PIXELS

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.django_db(transaction=True)]

PLAIN = ["study.practice=false", "study.catch_trials=0", "study.repeat_trials=0",
         "study.ask_demographics=false", "clips_per_source=1", "frames=20", "render.size=96",
         "actions=[walk,jump]", "slug=in-page", "render.player=webgl"]


@pytest.fixture(autouse=True)
def _real_watch(settings):
    settings.STUDY_WATCH_TIME_FACTOR = 1.0


@pytest.fixture
def study(transactional_db, media_root, tmp_path):
    config = load_config(DEMO_CONFIGS / "pairwise.yaml", PLAIN)
    study = build_stimuli(config, tmp_path / "build", cache=tmp_path / "cache").study
    assert study.player == "stick" and all(s.motion for s in study.stimuli.all())
    return study


def begin(page, url):
    page.goto(url)
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").click()


def answer_every_trial(page):
    while "/trial/" in page.url:
        current = page.locator("input[name=trial]").input_value()
        page.wait_for_function(ALL_WATCHED, timeout=20_000)
        page.locator(".choice-left").click()
        page.locator("[data-submit]").click()
        page.wait_for_function(
            "id => (document.querySelector('input[name=trial]') || {}).value !== id",
            arg=current, timeout=20_000)


@pytest.mark.parametrize("viewport", [{"width": 1280, "height": 860},
                                      {"width": 390, "height": 844}])
def test_the_motion_plays_in_the_page_and_the_answer_is_stored(browser, live_server, study,
                                                              viewport):
    context = browser.new_context(viewport=viewport, has_touch=viewport["width"] < 500)
    page = context.new_page()
    page.set_default_timeout(20_000)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    page.wait_for_selector("motion-player[src] canvas")
    # The canvas is there before its payload: wait until every player drew its first frame.
    page.wait_for_function(
        "[...document.querySelectorAll('motion-player')].every(p => 'frame' in p.dataset)")
    assert page.locator("[data-clip-card] video").count() == 0  # the fallback went
    submit = page.locator("[data-submit]")
    expect(submit).to_be_disabled()
    assert page.evaluate(FIGURE_PIXELS, [0, "stick"]) > 0.002  # a figure is drawn
    first = page.locator("motion-player").first.get_attribute("data-frame")
    page.wait_for_function(
        "f => document.querySelector('motion-player').dataset.frame !== f", arg=first)
    assert page.evaluate("document.documentElement.scrollWidth") <= viewport["width"]
    answer_every_trial(page)
    expect(page.locator("[data-completion-code]")).to_be_visible()
    context.close()
    person = Participant.objects.get()
    items = TrialItem.objects.filter(trial__participant=person)
    assert items.count() == 4 and not items.filter(fetched_at=None).exists()
    assert all(set(item.fetched) == {"motion"} for item in items)  # no mp4 was needed
    assert all(t.answers == {"preference": "left"} for t in person.trials.all())
    names = {name for t in person.trials.all() for _, name, _ in t.events}
    assert {"play", "ended"} <= names


def test_without_webgl_the_same_page_plays_the_videos(browser, live_server, study):
    context = browser.new_context()
    context.add_init_script(
        "const get = HTMLCanvasElement.prototype.getContext;"
        "HTMLCanvasElement.prototype.getContext = function (kind, ...rest) {"
        "  return kind === 'webgl2' ? null : get.call(this, kind, ...rest); };")
    page = context.new_page()
    page.set_default_timeout(20_000)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    page.wait_for_selector("[data-trial-form][data-ready]", state="attached")
    assert page.locator("motion-player").count() == 0
    assert page.locator("[data-clip-card] video").count() == 2
    answer_every_trial(page)
    expect(page.locator("[data-completion-code]")).to_be_visible()
    context.close()
    items = TrialItem.objects.filter(trial__participant=Participant.objects.get())
    assert all("mp4" in item.fetched for item in items)
