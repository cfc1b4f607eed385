"""A study played in the page (render.player: webgl) in a real Chromium, on desktop and
phone viewports: the canvas draws the figure and its frames advance, the answer unlocks
once every clip has looped, the server saw the payloads fetched and stores the answer;
without WebGL 2 the same page plays the mp4s; a payload that fails (404, corrupt bytes)
or a lost WebGL context brings the trial's videos back, and the server still decides from
the mp4s it sent."""

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
    names = {event[1] for t in person.trials.all() for event in t.events}
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


# The trial's players are gone, its two videos back, and the fallback is in its log.
BACK_TO_VIDEOS = ("() => !document.querySelector('motion-player')"
                  " && document.querySelectorAll('[data-clip-card] video').length === 2"
                  " && JSON.parse(document.querySelector('[data-events]').value || '[]')"
                  "    .some(e => e[1] === 'fallback')")


def trial_events(page):
    return page.evaluate("JSON.parse(document.querySelector('[data-events]').value || '[]')")


def payloads_fail(context, how):
    """Answer the page's payload requests as a broken network or an old build would."""
    seen = []

    def handle(route):
        seen.append(route.request.url)
        if how == "404":
            route.fulfill(status=404, body="gone")
        elif how == "corrupt":
            route.fulfill(status=200, body=b"\x00not a payload" * 40,
                          content_type="application/octet-stream")
        else:  # one clip of each trial fails, its neighbour loads and draws
            if len(seen) % 2:
                route.fulfill(status=404, body="gone")
            else:
                route.continue_()

    context.route("**/*.motion", handle)
    return seen


@pytest.mark.parametrize("how", ["404", "corrupt", "one"])
def test_a_payload_that_fails_brings_the_trials_videos_back(browser, live_server, study, how):
    context = browser.new_context()
    seen = payloads_fail(context, how)
    page = context.new_page()
    page.set_default_timeout(20_000)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    # The whole trial goes back to its videos, which play and count the plays.
    page.wait_for_function(BACK_TO_VIDEOS)
    page.wait_for_function(ALL_WATCHED, timeout=20_000)
    played = page.eval_on_selector_all("[data-clip-card] video", "vs => vs.map(v => v.played.length)")
    assert all(played)
    events = trial_events(page)
    fallback = [e for e in events if e[1] == "fallback"]
    assert len(fallback) == 1, events
    message = fallback[0][3]
    assert ("HTTP 404" in message) if how != "corrupt" else ("not a motion payload" in message)
    # Plays count from the videos only: every ended comes after the fallback.
    assert all(e[0] >= fallback[0][0] for e in events if e[1] == "ended")
    answer_every_trial(page)
    expect(page.locator("[data-completion-code]")).to_be_visible()
    context.close()
    person = Participant.objects.get()
    assert all(t.answers == {"preference": "left"} for t in person.trials.all())
    for trial in person.trials.all():
        assert [e[1] for e in trial.events].count("fallback") == 1, trial.events
    items = TrialItem.objects.filter(trial__participant=person)
    assert len(seen) == items.count()  # every clip asked for its payload first
    assert not items.filter(fetched_at=None).exists()
    # The server's own record: the videos it sent whole (the failed payloads never came
    # from it); a payload the server did send whole counts as for any player trial.
    failed = seen[0::2] if how == "one" else seen
    for item in items:
        if any(f"/{item.token}.motion" in url for url in failed):
            assert set(item.fetched) == {"mp4"}, item.fetched
        else:
            assert set(item.fetched) <= {"mp4", "motion"} and item.fetched, item.fetched


def test_after_a_fallback_the_server_still_wants_the_videos(browser, live_server, study):
    """The page's say-so is not enough: with the payloads and the mp4s both lost on the
    way, a post claiming every clip played is refused and nothing is stored."""
    context = browser.new_context()
    payloads_fail(context, "404")
    context.route("**/*.mp4", lambda route: route.abort())
    page = context.new_page()
    page.set_default_timeout(20_000)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    page.wait_for_function(BACK_TO_VIDEOS)
    page.wait_for_timeout(1500)  # longer than the clips: only the fetch is missing
    page.evaluate("document.querySelectorAll('[data-plays]').forEach(i => { i.value = '1'; })")
    page.locator(".choice-left").click()
    page.evaluate("document.querySelector('[data-submit]').disabled = false")
    page.locator("[data-submit]").click()
    page.wait_for_load_state()
    assert "has not been loaded to its end yet" in page.content()
    context.close()
    person = Participant.objects.get()
    assert not person.trials.filter(answered_at__isnull=False).exists()
    assert not TrialItem.objects.filter(trial__participant=person).exclude(fetched_at=None).exists()


def test_a_lost_webgl_context_brings_the_trials_videos_back(browser, live_server, study):
    """The GPU goes away once the players drew: the first trial finishes on its videos,
    the next page plays in the page again."""
    context = browser.new_context()
    context.add_init_script(
        "window.__contexts = [];"
        "const get = HTMLCanvasElement.prototype.getContext;"
        "HTMLCanvasElement.prototype.getContext = function (kind, ...rest) {"
        "  const made = get.call(this, kind, ...rest);"
        "  if (kind === 'webgl2' && made) window.__contexts.push(made);"
        "  return made; };")
    page = context.new_page()
    page.set_default_timeout(20_000)
    begin(page, f"{live_server.url}/s/{study.slug}/")
    page.wait_for_function(
        "[...document.querySelectorAll('motion-player')].every(p => 'frame' in p.dataset)")
    page.evaluate("window.__contexts.at(-1).getExtension('WEBGL_lose_context').loseContext()")
    page.wait_for_function(BACK_TO_VIDEOS)
    fallback = [e for e in trial_events(page) if e[1] == "fallback"]
    assert fallback == [[fallback[0][0], "fallback", None, "WebGL context lost"]]
    page.wait_for_function(ALL_WATCHED, timeout=20_000)
    first = page.locator("input[name=trial]").input_value()
    page.locator(".choice-left").click()
    page.locator("[data-submit]").click()
    page.wait_for_function(
        "id => (document.querySelector('input[name=trial]') || {}).value !== id",
        arg=first, timeout=20_000)
    page.wait_for_function(
        "[...document.querySelectorAll('motion-player')].every(p => 'frame' in p.dataset)"
        " && document.querySelectorAll('motion-player').length === 2")
    answer_every_trial(page)
    expect(page.locator("[data-completion-code]")).to_be_visible()
    context.close()
    trials = list(Participant.objects.get().trials.order_by("index"))
    assert [[e[1] for e in t.events].count("fallback") for t in trials] == [1, 0]
    assert all(t.answers == {"preference": "left"} for t in trials)
    assert not TrialItem.objects.filter(trial__in=trials, fetched_at=None).exists()
