"""Every registered type's trial page fits a laptop and a phone in a real Chromium: the
clips to judge, the answer controls and the submit button in one screen on a 1280x800
laptop; on a 390x844 phone no label cut or wrapped mid-name and no page wider than the
screen; no keyboard-key hints on a touch screen. The practice shows as many clips as a
trial does. And on both screens every clip's figure stays inside its video frame while
it plays (clips rendered as a build renders them, in one framing: a walk that side-steps,
a figure floating up, catch clips and a low anchor among them)."""

import random

import numpy as np
import pytest

from studyapp.survey.models import Trial
from studyapp.survey.study_types import get_study_type, list_study_types
from tests.rendering.conftest import drifting_walk, make_figure, rising_figure, shaken_anchor
from tests.studyapp.conftest import make_study
from tests.studyapp.test_browser import snap

pytestmark = pytest.mark.django_db(transaction=True)

VIEWPORTS = {
    "laptop": {"viewport": {"width": 1280, "height": 800}},
    "phone": {"viewport": {"width": 390, "height": 844}, "device_scale_factor": 2,
              "is_mobile": True, "has_touch": True},
}

# What the page holds: boxes of the clips to judge (and those required beside them), of the
# answer controls and the submit bar; labels that must not be cut; visible key hints.
MEASURE = """() => {
  const box = el => { const r = el.getBoundingClientRect(); return {top: r.top, bottom: r.bottom,
                      left: r.left, right: r.right, width: r.width, height: r.height}; };
  const shown = el => { const s = getComputedStyle(el); const r = el.getBoundingClientRect();
                        return s.display !== 'none' && s.visibility !== 'hidden' && r.width > 0; };
  const form = document.querySelector('[data-trial-form]');
  const clips = [...form.querySelectorAll('[data-clip-card][data-role=judged] .clip-frame')].map(box);
  const controls = [...form.querySelectorAll(
      'input:not([type=hidden]), select, textarea, .rank-row, .choice')]
    .filter(el => !el.closest('.submit-bar') && !el.closest('details:not([open])'))
    .filter(el => el.type !== 'radio' && el.type !== 'checkbox' || !el.closest('.choice'))
    .filter(shown).map(box);
  const labels = [...form.querySelectorAll(
      '.clip-name, .clip-state, .choice span, legend, .rank-name, .gate, button, label')]
    .filter(shown).filter(el => !el.closest('.sr-only'))
    .filter(el => el.scrollWidth > el.clientWidth + 1)
    .map(el => el.className + ': ' + el.textContent.trim().slice(0, 40));
  const wrapped = [...form.querySelectorAll('.clip-name')].filter(shown)
    .filter(el => el.getBoundingClientRect().height > 1.6 * parseFloat(getComputedStyle(el).lineHeight || 20))
    .map(el => el.textContent.trim());
  const keys = [...document.querySelectorAll('kbd')].filter(shown).map(el => el.textContent);
  const bar = document.querySelector('.submit-bar').getBoundingClientRect();
  const first = form.querySelector('[data-clip-card][data-role=judged]');
  const clipsAt = first.getBoundingClientRect().top + scrollY;
  return {clips, controls, labels, wrapped, keys, clipsAt, barTop: bar.top, height: innerHeight,
          width: document.documentElement.clientWidth,
          scrollWidth: document.documentElement.scrollWidth};
}"""


def first_trial(browser, viewport, url):
    """Open ``url`` in a fresh context of ``viewport``; consent, start; return the page on
    the first trial with its clips loaded."""
    context = browser.new_context(**VIEWPORTS[viewport])
    page = context.new_page()
    page.set_default_timeout(15_000)
    page.goto(url)
    page.get_by_label("I have read the information above").check()
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("[data-trial-form]")
    page.wait_for_function("() => [...document.querySelectorAll('video')]"
                           ".every(v => v.readyState >= 1 || v.preload === 'none')")
    return context, page


@pytest.mark.browser
@pytest.mark.parametrize("key", list_study_types())
def test_a_trial_fits_a_laptop_and_a_phone(browser, live_server, media_root, clips,
                                           extra_clips, key):
    study = make_study(key, clips, extra_clips, slug=f"fit-{key.replace('_', '-')}",
                       trials_per_participant=2)
    problems = []
    for viewport in VIEWPORTS:
        context, page = first_trial(browser, viewport, f"{live_server.url}/s/{study.slug}/")
        try:
            # As it opens: a page whose clips start high up shows all it asks unscrolled.
            opened = page.evaluate(MEASURE)
            # Scrolled to the first clip's top (as a person does to see the clips).
            page.evaluate("() => { const c = document.querySelector("
                          "'[data-clip-card][data-role=judged]'); window.scrollTo(0, "
                          "Math.max(0, c.getBoundingClientRect().top + scrollY - 8)); }")
            page.wait_for_timeout(50)
            m = page.evaluate(MEASURE)
            snap(page, f"fit-{key}-{viewport}")
        finally:
            context.close()
        where = f"{key} on a {viewport}"
        if m["scrollWidth"] > m["width"]:
            problems.append(f"{where}: the page is {m['scrollWidth']} px wide in {m['width']}")
        if m["labels"]:
            problems.append(f"{where}: labels cut: {m['labels']}")
        if m["wrapped"]:
            problems.append(f"{where}: clip names wrap: {m['wrapped']}")
        if m["clipsAt"] > 1.2 * m["height"]:
            problems.append(f"{where}: the clips to judge start {m['clipsAt']:.0f} px down")
        if viewport == "phone" and m["keys"]:
            problems.append(f"{where}: key hints on a touch screen: {m['keys']}")
        if viewport == "laptop":
            views = [("scrolled to the clips", m)]
            if opened["clips"][0]["top"] < 0.4 * opened["height"]:
                views.append(("as it opens", opened))
            for how, seen in views:
                boxes = seen["controls"] + seen["clips"]
                below = [c for c in boxes if c["bottom"] > seen["barTop"] + 1]
                above = [c for c in boxes if c["top"] < -1]
                if below or above:
                    problems.append(f"{where} {how}: {len(below)} clips or controls under "
                                    f"the submit bar (at {seen['barTop']:.0f} px), "
                                    f"{len(above)} above the screen; lowest at "
                                    f"{max(c['bottom'] for c in boxes):.0f} px")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("key", list_study_types())
def test_the_practice_shows_as_many_clips_as_a_trial(media_root, clips, extra_clips, key):
    kind = get_study_type(key)
    study = make_study(key, clips, extra_clips, slug=f"practice-{key.replace('_', '-')}",
                       practice=True, trials_per_participant=2)
    assert kind.stimulus_roles({"practice": True, "clips_per_trial": 4})["practice"] >= 4
    plans = kind.plan_trials(study, random.Random(1))
    practice = [p for p in plans if p.kind == Trial.Kind.PRACTICE]
    main = [p for p in plans if p.kind == Trial.Kind.MAIN]
    assert practice and main
    assert len(practice[0].stimuli) == len(main[0].stimuli)


FIGURE_FRAMES = 30
FIGURE_SIZE = 96

# Seek every clip on the trial page to a few moments and find the figure's box: the
# warm and cool limbs are strongly saturated, the scenery grey.
FIGURE_BOXES = """async (times) => {
  const out = [];
  for (const v of document.querySelectorAll('[data-trial-form] video')) {
    v.preload = 'auto';
    if (v.readyState < 2) {
      v.load();
      await new Promise(r => v.readyState >= 2 ? r() : v.addEventListener('loadeddata', r, {once: true}));
    }
    v.pause();
    const canvas = document.createElement('canvas');
    canvas.width = v.videoWidth; canvas.height = v.videoHeight;
    const context = canvas.getContext('2d', {willReadFrequently: true});
    const boxes = [];
    for (const share of times) {
      await new Promise(r => { v.addEventListener('seeked', r, {once: true});
                               v.currentTime = share * v.duration; });
      context.drawImage(v, 0, 0);
      const data = context.getImageData(0, 0, canvas.width, canvas.height).data;
      let left = Infinity, top = Infinity, right = -1, bottom = -1;
      for (let y = 0; y < canvas.height; y++) for (let x = 0; x < canvas.width; x++) {
        const i = 4 * (y * canvas.width + x);
        const r = data[i], g = data[i + 1], b = data[i + 2];
        if (Math.max(r, g, b) - Math.min(r, g, b) > 60) {
          left = Math.min(left, x); right = Math.max(right, x);
          top = Math.min(top, y); bottom = Math.max(bottom, y);
        }
      }
      boxes.push(right < 0 ? null : [left, top, right, bottom]);
    }
    const card = v.closest('[data-clip-card]');
    out.push({role: card ? card.dataset.role : '', width: v.videoWidth, height: v.videoHeight,
              boxes});
  }
  return out;
}"""


@pytest.fixture(scope="module")
def figure_clips(tmp_path_factory):
    """Return judged clips (2 actions x 3 sources) and, per action, a reference, five
    scoring-standard examples, a catch clip and a low anchor, rendered in one framing
    as a build renders them: among the judged, a generated walk that side-steps and a
    generated wave whose figure floats up; the catch clips float up too."""
    from motion import perturb
    from rendering import Framing, render_set
    from studyapp.stimuli.clips import Clip

    frames, fps = FIGURE_FRAMES, 25.0
    shown = []  # (motion, role, score)
    for a, action in enumerate(("walk", "wave")):
        for s, source in enumerate(("real", "a2m", "cond_gru")):
            if (action, source) == ("walk", "cond_gru"):
                motion = drifting_walk(frames, fps, at=0.5)  # a walk of cond_gru
            elif (action, source) == ("wave", "a2m"):
                motion = rising_figure(frames, fps, at=0.3, source=source, action=action,
                                       phase=0.3)
            else:
                motion = make_figure(frames=frames, speed=0.8 + 0.3 * s, action=action,
                                     source=source, phase=a + 0.7 * s)
            shown.append((motion, "judged", None))
        root = make_figure(frames=frames, speed=1.0, action=action, phase=2.0 + a)
        shown.append((make_figure(frames=frames, speed=1.1, action=action, phase=0.5 + a),
                      "reference", None))
        rng = np.random.default_rng(7 + a)
        for score, example in perturb.standard_examples(root, rng).items():
            shown.append((example.with_joints(example.joints, action=action), "example", score))
        catch = rising_figure(frames, fps, at=0.3, action=action, phase=1.0 + a)
        shown.append((catch, "catch", None))
        anchor = shaken_anchor(frames, fps, seed=3 + a, action=action)
        shown.append((anchor.with_joints(anchor.joints, action=action), "anchor", None))
    motions = [m for m, _, _ in shown]
    framing = Framing.from_motions(motions)
    out = tmp_path_factory.mktemp("figure-clips")
    report = render_set(motions, out, size=FIGURE_SIZE, framing=framing, progress=False)
    judged, extra = [], []
    for done, (motion, role, score) in zip(sorted(report.clips, key=lambda c: c.index), shown):
        if role == "judged":
            judged.append(Clip.rendered(motion, done))
        else:
            extra.append(Clip.rendered(motion, done, role=role, score=score))
    return judged, extra


@pytest.mark.browser
@pytest.mark.parametrize("key", list_study_types())
def test_the_figure_stays_inside_every_clip_on_a_laptop_and_a_phone(
        browser, live_server, media_root, figure_clips, key):
    """Each clip of the first trial (judged clips, and the reference, examples and anchor
    where the type shows them), drawn into a canvas at eight moments: the figure's box
    never reaches the video frame's outermost rows or columns (nothing of it cut)."""
    judged, extra = figure_clips
    study = make_study(key, judged, extra, slug=f"figure-fit-{key.replace('_', '-')}",
                       trials_per_participant=2, catch=True)
    problems, checked = [], 0
    for viewport in VIEWPORTS:
        context, page = first_trial(browser, viewport, f"{live_server.url}/s/{study.slug}/")
        try:
            clips = page.evaluate(FIGURE_BOXES, [0.02, 0.15, 0.3, 0.45, 0.6, 0.75, 0.88, 0.98])
        finally:
            context.close()
        assert clips, f"{key} on a {viewport}: no clip on the first trial"
        for number, clip in enumerate(clips):
            where = f"{key} on a {viewport}, clip {number} ({clip['role']})"
            assert (clip["width"], clip["height"]) == (FIGURE_SIZE, FIGURE_SIZE), where
            for moment, box in enumerate(clip["boxes"]):
                checked += 1
                if box is None:
                    problems.append(f"{where}: no figure at moment {moment}")
                elif min(box[:2]) < 1 or max(box[2:]) > FIGURE_SIZE - 2:
                    problems.append(f"{where}: the figure reaches the frame's edge at "
                                    f"moment {moment}: box {box}")
    assert checked and not problems, "\n".join(problems)
