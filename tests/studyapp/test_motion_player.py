"""The in-browser player in a real Chromium (WebGL 2 in software): it draws, advances,
loops with one `ended` per loop, keeps players in sync and answers touch, and frames a
clip as its rendered video does (a figure that drifts or rises stays inside)."""

import functools
import http.server
import threading
from pathlib import Path

import numpy as np
import pytest

from rendering import Framing, get_style
from rendering.player import write_payloads
from tests.rendering.conftest import drifting_walk, make_figure, rising_figure, shaken_anchor
from tests.rendering.helpers import figure_box


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Serve files without a log line per request."""

    def log_message(self, *args):
        pass

pytestmark = [pytest.mark.browser, pytest.mark.slow]

STATIC = Path(__file__).resolve().parents[2] / "studyapp" / "survey" / "static" / "survey"
HARNESS = Path(__file__).resolve().parent / "data" / "motion_player.html"
FRAMES = 20  # 0.8 s at 25 fps: loops come quickly
CANVAS = 240  # the harness's players: 240 CSS px, so 240 pixels at a pixel ratio of 1


def _serve(root, motions, framing, size=480):
    """Serve the player, three.js, the harness and the motions' payloads from ``root``
    over local HTTP; yield the harness's URL."""
    for name in ("player", "vendor"):
        (root / name).symlink_to(STATIC / name, target_is_directory=True)
    (root / "index.html").write_text(HARNESS.read_text())
    names = [path.name for path, _ in write_payloads(motions, root, framing, size)]
    handler = functools.partial(QuietHandler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/index.html?clips={','.join(names)}"
    server.shutdown()


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """Two payloads of a walker and a swayer."""
    walker = make_figure(frames=FRAMES, speed=1.0)
    swayer = make_figure(frames=FRAMES, phase=1.5)
    yield from _serve(tmp_path_factory.mktemp("player-site"), [walker, swayer],
                      Framing.from_motions([walker, swayer]))


@pytest.fixture(scope="module")
def moving(tmp_path_factory):
    """A walk that side-steps faster than the camera follows, a figure that rises off the
    floor and an anchor shaken apart (each left the frame under the rule's follow camera
    alone; the anchor is filmed from farther away), framed with a real walk, their
    payloads made for the player's 240-pixel canvas."""
    real = make_figure(frames=50, speed=1.2)
    clips = [drifting_walk(), rising_figure(), shaken_anchor()]
    framing = Framing.from_motions([real, *clips])
    url = _serve(tmp_path_factory.mktemp("player-moving"), clips, framing, CANVAS)
    yield next(url), clips, framing
    next(url, None)


def _open(page, url, figure="stick", players=2):
    page.goto(f"{url}&figure={figure}")
    assert page.evaluate("window.webgl2"), "WebGL 2 missing: pages would fall back to the mp4"
    page.wait_for_function(
        f"window.events.filter(e => e.type === 'loadeddata').length === {players}")
    assert not [e for e in page.evaluate("window.events") if e["type"] == "error"]


# Counted in the page (shipping every pixel out is slow): strongly saturated pixels for
# sticks (warm left, cool right limbs), dark ones above the floor and its shadow for bodies.
FIGURE_PIXELS = """([index, figure]) => {
    const canvas = document.querySelectorAll('motion-player canvas')[index];
    const {width, height} = canvas;
    const data = canvas.getContext('2d').getImageData(0, 0, width, height).data;
    let count = 0;
    for (let y = 0; y < height; y++) {
        if (figure === 'body' && (y < 0.2 * height || y > 0.55 * height)) continue;
        for (let x = 0; x < width; x++) {
            const k = 4 * (y * width + x), r = data[k], g = data[k + 1], b = data[k + 2];
            const high = Math.max(r, g, b), low = Math.min(r, g, b);
            if (figure === 'stick' ? high - low > 60 : high < 200) count++;
        }
    }
    return count / (width * height); }"""


def _plays(page, url, figure):
    _open(page, url, figure)
    for index in (0, 1):
        assert page.evaluate(FIGURE_PIXELS, [index, figure]) > 0.002, f"no {figure} drawn"
    page.evaluate("playback.play()")
    page.wait_for_function(
        "window.events.filter(e => e.type === 'ended').length >= 4", timeout=20_000)
    frames = set()
    for _ in range(12):
        pair = page.evaluate(
            "[...document.querySelectorAll('motion-player')].map(p => +p.dataset.frame)")
        assert pair[0] == pair[1], "players out of sync"
        frames.add(pair[0])
        page.wait_for_timeout(60)
    assert len(frames) >= 4, f"frames do not advance: {frames}"
    events = page.evaluate("window.events")
    ended = [e for e in events if e["type"] == "ended"]
    per_clip = {e["clip"]: 0 for e in ended}
    for e in ended:
        per_clip[e["clip"]] += 1
    assert len(per_clip) == 2 and max(per_clip.values()) - min(per_clip.values()) <= 1
    assert [e["type"] for e in events if e["type"] == "play"] == ["play", "play"]


@pytest.mark.parametrize("figure", ["stick", "body"])
def test_players_draw_loop_and_stay_in_sync_on_desktop(page, site, figure):
    _plays(page, site, figure)
    page.evaluate("playback.pause()")
    frame = page.evaluate("document.querySelector('motion-player').dataset.frame")
    page.wait_for_timeout(300)
    assert page.evaluate("document.querySelector('motion-player').dataset.frame") == frame
    page.evaluate("playback.seek(0.4)")
    page.wait_for_function("document.querySelector('motion-player').dataset.frame === '10'")
    kinds = [e["type"] for e in page.evaluate("window.events")]
    assert kinds.count("pause") == 2 and kinds.count("seek") == 2


def test_a_tap_pauses_and_resumes_on_a_phone(phone_page, site):
    _plays(phone_page, site, "stick")
    width = phone_page.evaluate("document.querySelector('motion-player canvas').width")
    assert width >= 2 * 160, "the canvas should use the phone's pixel ratio"
    phone_page.locator("motion-player").first.tap()
    phone_page.wait_for_function("window.playback.paused")
    phone_page.locator("motion-player").nth(1).tap()
    phone_page.wait_for_function("!window.playback.paused")
    causes = [(e["type"], e["cause"]) for e in phone_page.evaluate("window.events")
              if e["type"] in ("pause", "play")]
    assert causes[-4:] == [("pause", "user")] * 2 + [("play", "user")] * 2


# The box of the saturated (limb) pixels of each player's canvas, as figure_box reads a
# video frame: [left, top, right, bottom], or null.
CANVAS_BOXES = """() => [...document.querySelectorAll('motion-player canvas')].map((canvas) => {
    const {width, height} = canvas;
    const data = canvas.getContext('2d').getImageData(0, 0, width, height).data;
    let box = null;
    for (let y = 0; y < height; y++) {
        for (let x = 0; x < width; x++) {
            const k = 4 * (y * width + x), r = data[k], g = data[k + 1], b = data[k + 2];
            if (Math.max(r, g, b) - Math.min(r, g, b) <= 60) continue;
            box = box ? [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x),
                         Math.max(box[3], y)] : [x, y, x, y];
        }
    }
    return {size: [width, height], box}; })"""


def _video_frames(motion, framing):
    """Return where the clip's video of CANVAS pixels shows each joint on each frame
    ``(T, J, 2)``, and its frames as the stick style draws them (before encoding)."""
    with get_style("stick")(framing, CANVAS, CANVAS) as drawer:
        placed = framing.place(motion)
        shot = framing.shot(motion, CANVAS, CANVAS, drawer.reach(motion.skeleton), placed)
        camera = shot.camera(CANVAS, CANVAS)
        pixels, _ = camera.project_each(placed, shot.targets - np.asarray(shot.framing.target))
        pixels -= (np.asarray(shot.margin) + shot.offsets)[:, None, :]
        return pixels, list(drawer.frames(motion)), shot


def test_a_drifting_or_rising_figure_is_framed_as_in_its_video(page, moving):
    """At seven moments the player's figure stays inside its canvas, each joint shows
    where the clip's video (rendering.framing.Framing.shot) shows it, and the figure's
    box is the video frame's."""
    url, clips, framing = moving
    _open(page, url, players=len(clips))
    videos = [_video_frames(motion, framing) for motion in clips]
    for (_, _, shot), name in zip(videos[:2], ("drift", "rise")):
        assert np.abs(shot.offsets).max() > 0.05 * CANVAS, f"{name}: the window never moves"
    assert videos[2][2].framing.distance > 1.05 * framing.distance, "the anchor is not zoomed"
    problems = []
    for frame in (0, 12, 24, 30, 36, 42, 49):
        page.evaluate(f"playback.seek({(frame + 0.5) / 25})")
        page.wait_for_function(
            f"[...document.querySelectorAll('motion-player')].every(p => p.frame === {frame})")
        shown = page.evaluate(CANVAS_BOXES)
        joints = page.evaluate(
            f"[...document.querySelectorAll('motion-player')].map(p => p.pixels({frame}))")
        for number, ((pixels, frames, _), canvas, player) in enumerate(zip(videos, shown, joints)):
            where = f"clip {number}, frame {frame}"
            assert canvas["size"] == [CANVAS, CANVAS], where
            box = canvas["box"]
            if box is None or min(box[:2]) < 1 or max(box[2:]) > CANVAS - 2:
                problems.append(f"{where}: the figure reaches the canvas's edge: {box}")
            apart = np.abs(np.asarray(player) - pixels[frame]).max()
            if apart > 0.5:
                problems.append(f"{where}: joints {apart:.2f} px from the video's")
            video_box = np.asarray(figure_box(frames[frame]))
            if box is not None and np.abs(np.asarray(box) - video_box).max() > 4:
                problems.append(f"{where}: box {box}, the video's {video_box.tolist()}")
    assert not problems, "\n".join(problems)
