"""Padded constant-rate clips play to their end in a real Chromium, all alike."""

import functools
import http.server
import threading

import numpy as np
import pytest

from rendering import render_set
from tests.rendering.conftest import make_figure


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Serve files without a log line per request."""

    def log_message(self, *args):
        pass

pytestmark = pytest.mark.browser

FRAMES = 20


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """Render a still and a jittered clip, and serve their folder over local HTTP."""
    out = tmp_path_factory.mktemp("playback")
    walker = make_figure(frames=FRAMES, speed=1.5)
    still = walker.with_joints(np.repeat(walker.joints[:1], FRAMES, axis=0))
    rng = np.random.default_rng(0)
    broken = walker.with_joints((walker.joints + rng.normal(scale=0.3, size=walker.joints.shape))
                                .astype(np.float32), source="broken")
    report = render_set([still, broken], out, size=96, progress=False, formats=("mp4", "webm"))
    names = [(c.video.name, c.extras["webm"].name) for c in report.clips]
    (out / "index.html").write_text("<!doctype html><body>" + "".join(
        f'<video src="{name}" muted playsinline preload="auto"></video>'
        for pair in names for name in pair) + "</body>")
    handler = functools.partial(QuietHandler, directory=str(out))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}/index.html"
    server.shutdown()


def test_still_and_jittered_clips_play_to_the_end_alike(page, served):
    page.goto(served)
    page.evaluate("""() => { window.ended = 0;
        for (const v of document.querySelectorAll('video')) {
            v.addEventListener('ended', () => window.ended++); v.play(); } }""")
    page.wait_for_function("window.ended === document.querySelectorAll('video').length")
    videos = page.eval_on_selector_all(
        "video", "vs => vs.map(v => ({error: v.error && v.error.code, width: v.videoWidth,"
        " height: v.videoHeight, duration: v.duration, played: v.played.length}))")
    assert len(videos) == 4
    for video in videos:
        assert video["error"] is None and video["played"] > 0
        assert (video["width"], video["height"]) == (96, 96)
        assert video["duration"] == pytest.approx(FRAMES / 25, abs=0.05)
