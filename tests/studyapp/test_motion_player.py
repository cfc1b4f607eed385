"""The in-browser player in a real Chromium (WebGL 2 in software): it draws, advances,
loops with one `ended` per loop, keeps players in sync and answers touch."""

import functools
import http.server
import threading
from pathlib import Path

import pytest

from rendering import Framing
from rendering.player import write_payloads
from tests.rendering.conftest import make_figure


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Serve files without a log line per request."""

    def log_message(self, *args):
        pass

pytestmark = [pytest.mark.browser, pytest.mark.slow]

STATIC = Path(__file__).resolve().parents[2] / "studyapp" / "survey" / "static" / "survey"
HARNESS = Path(__file__).resolve().parent / "data" / "motion_player.html"
FRAMES = 20  # 0.8 s at 25 fps: loops come quickly


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """Serve the player, three.js, the harness and two payloads over local HTTP."""
    root = tmp_path_factory.mktemp("player-site")
    for name in ("player", "vendor"):
        (root / name).symlink_to(STATIC / name, target_is_directory=True)
    (root / "index.html").write_text(HARNESS.read_text())
    walker = make_figure(frames=FRAMES, speed=1.0)
    swayer = make_figure(frames=FRAMES, phase=1.5)
    framing = Framing.from_motions([walker, swayer])
    names = [path.name for path, _ in write_payloads([walker, swayer], root, framing)]
    handler = functools.partial(QuietHandler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/index.html?clips={','.join(names)}"
    server.shutdown()


def _open(page, url, figure="stick"):
    page.goto(f"{url}&figure={figure}")
    assert page.evaluate("window.webgl2"), "WebGL 2 missing: pages would fall back to the mp4"
    page.wait_for_function("window.events.filter(e => e.type === 'loadeddata').length === 2")
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
