"""Padded constant-rate clips, and per-delivery variants of them (their filler split
anew, rendering.delivery), play to their end in a real Chromium, all alike."""

import functools
import http.server
import threading

import numpy as np
import pytest

from rendering import render_set
from rendering.delivery import deliver
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
    for clip in report.clips:
        for k in range(2):  # two deliveries of each mp4, as two participants get them
            delivered = out / f"delivery{k}-{clip.video.name}"
            delivered.write_bytes(deliver(clip.video.read_bytes(), "mp4", bytes([k + 1]) * 32))
            names.append((delivered.name,))
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
    assert len(videos) == 8
    for video in videos:
        assert video["error"] is None and video["played"] > 0
        assert (video["width"], video["height"]) == (96, 96)
        assert video["duration"] == pytest.approx(FRAMES / 25, abs=0.05)


def test_deliveries_of_a_clip_show_chromium_the_same_frames(page, served):
    """Seek every mp4 to a few moments and read its pixels off a canvas: each delivery
    shows exactly the frames of the stored file."""
    page.goto(served)
    pixels = page.evaluate("""async () => {
        const out = {};
        for (const v of document.querySelectorAll('video')) {
            const name = v.getAttribute('src');
            if (!name.endsWith('.mp4')) continue;
            await new Promise(r => v.readyState >= 2 ? r() : v.addEventListener('loadeddata', r, {once: true}));
            const canvas = document.createElement('canvas');
            canvas.width = v.videoWidth; canvas.height = v.videoHeight;
            const context = canvas.getContext('2d');
            out[name] = [];
            for (const t of [0.02, 0.3, 0.7]) {
                await new Promise(r => { v.addEventListener('seeked', r, {once: true}); v.currentTime = t; });
                context.drawImage(v, 0, 0);
                const data = context.getImageData(0, 0, canvas.width, canvas.height).data;
                let sum = 0, weighted = 0;
                for (let i = 0; i < data.length; i++) { sum += data[i]; weighted += data[i] * (i % 251); }
                out[name].push([sum, weighted]);
            }
        }
        return out; }""")
    stored = [name for name in pixels if not name.startswith("delivery")]
    assert len(stored) == 2 and len(pixels) == 6
    for name in stored:
        for k in range(2):
            assert pixels[f"delivery{k}-{name}"] == pixels[name]
    assert pixels[stored[0]] != pixels[stored[1]]
