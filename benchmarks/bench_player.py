"""The in-browser player against the mp4: bytes per clip and time to the first frame.

    .venv/bin/python benchmarks/bench_player.py           # print the table
    .venv/bin/python benchmarks/bench_player.py --write   # and update docs/BENCHMARKS.md

A trial page of 4 clips (demo walking clips, stick style) is opened in Debian's Chromium
(headless, software WebGL) from a local HTTP server, once as <video> elements playing the
rendered mp4s and once as <motion-player> elements playing the payloads, cold (a new
browser context, nothing cached) and warm (the same context again). Time to first frame
is from the start of navigation to the last of the 4 clips' first frames on screen:
``requestVideoFrameCallback`` for videos, the player's ``loadeddata`` event (after its
first draw) for payloads.
"""

from __future__ import annotations

import argparse
import functools
import gzip
import http.server
import os
import re
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from motion.datasets import get_dataset  # noqa: E402
from rendering import render_set  # noqa: E402
from rendering.player import write_payloads  # noqa: E402


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    """Serve files without a log line per request."""

    def log_message(self, *args):
        pass

STATIC = ROOT / "studyapp" / "survey" / "static" / "survey"
DOCS = ROOT / "docs" / "BENCHMARKS.md"
HEADING = "## In-browser player"
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
CLIPS = 4

VIDEO_PAGE = """<!doctype html><body>{items}<script>
window.firsts = [];
for (const v of document.querySelectorAll('video')) {{
  v.requestVideoFrameCallback(() => window.firsts.push(performance.now()));
  v.play();
}}
</script></body>"""
PLAYER_PAGE = """<!doctype html><body><style>motion-player{{display:block;width:240px;
height:240px}}</style>{items}<script type="module">
import {{ playback }} from './player/motion-player.js';
window.ready = performance.now();  // three.js and the player fetched, parsed and run
window.firsts = [];
for (const p of document.querySelectorAll('motion-player')) {{
  p.addEventListener('loadeddata', () => window.firsts.push(performance.now()));
}}
playback.play();
</script></body>"""


def build_site(folder: Path, size: int) -> tuple[list[Path], list[Path]]:
    """Render the clips as mp4s and payloads in one framing, and write both pages."""
    clips = [m for m in get_dataset("demo").clips() if m.action == "walk"][:CLIPS]
    report = render_set(clips, folder, size=size, progress=False)
    payloads = [path for path, _ in write_payloads(clips, folder, report.framing, size)]
    for name in ("player", "vendor"):
        (folder / name).symlink_to(STATIC / name, target_is_directory=True)
    videos = [clip.video for clip in report.clips]
    (folder / "videos.html").write_text(VIDEO_PAGE.format(items="".join(
        f'<video src="{v.name}" muted playsinline preload="auto" width="240" height="240">'
        "</video>" for v in videos)))
    (folder / "players.html").write_text(PLAYER_PAGE.format(items="".join(
        f'<motion-player src="{p.name}"></motion-player>' for p in payloads)))
    return videos, payloads


def serve(folder: Path):
    handler = functools.partial(QuietHandler, directory=str(folder))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}"


def first_frames(browser, url: str, rounds: int) -> dict[str, float]:
    """Return the median cold and warm milliseconds to the last clip's first frame."""
    cold, warm, ready = [], [], []
    for _ in range(rounds):
        context = browser.new_context(viewport={"width": 1100, "height": 400})
        page = context.new_page()
        for times in (cold, warm):
            page.goto(url)
            page.wait_for_function(f"window.firsts.length === {CLIPS}", timeout=60_000)
            times.append(page.evaluate("Math.max(...window.firsts)"))
            ready.append(page.evaluate("window.ready || 0"))
        context.close()
    return {"cold": float(np.median(cold)), "warm": float(np.median(warm)),
            "ready_cold": float(np.median(ready[0::2])), "ready_warm": float(np.median(ready[1::2]))}


def measure(size: int, rounds: int) -> dict:
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="bench-player-") as name:
        folder = Path(name)
        videos, payloads = build_site(folder, size)
        server, base = serve(folder)
        try:
            with sync_playwright() as playwright:
                browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
                times = {"mp4": first_frames(browser, f"{base}/videos.html", rounds),
                         "player": first_frames(browser, f"{base}/players.html", rounds)}
                browser.close()
        finally:
            server.shutdown()
        scripts = sorted((STATIC / "vendor" / "three").glob("*.js"))
        library = sum(p.stat().st_size for p in scripts)
        compressed = sum(len(gzip.compress(p.read_bytes(), 6)) for p in scripts)
        player = (STATIC / "player" / "motion-player.js").stat().st_size
        return {
            "mp4": videos[0].stat().st_size, "poster": videos[0].with_suffix(".png").stat().st_size,
            "payload": payloads[0].stat().st_size, "library": library, "player_js": player,
            "library_gzip": compressed,
            "payload_gzip": len(gzip.compress(payloads[0].read_bytes(), 6)),
            "frames": 60, "size": size, "times": times, "rounds": rounds,
            "load": os.getloadavg()[0],
        }


def section(result: dict) -> str:
    mp4, payload, times = result["mp4"], result["payload"], result["times"]
    return "\n".join([
        HEADING,
        "",
        f"`benchmarks/bench_player.py`: a page of {CLIPS} clips of 60 frames (demo walking, "
        f"stick style, {result['size']}×{result['size']} mp4s; the player draws at 240×240 CSS "
        "px) in Debian's Chromium, headless with software WebGL 2 (no GPU), from a local "
        f"HTTP server; medians of {result['rounds']} rounds, on 2 CPU cores shared with other "
        f"work (load average {result['load']:.1f}), so times vary with the load. Cold: a new "
        "browser context; warm: the same page again.",
        "",
        "| clip as | bytes per clip | page's script (once) | first frame of all 4, cold (ms) "
        "| warm (ms) |",
        "|---|---:|---:|---:|---:|",
        f"| mp4 (constant rate, padded) + poster | {mp4:,} + {result['poster']:,} | — | "
        f"{times['mp4']['cold']:.0f} | {times['mp4']['warm']:.0f} |",
        f"| payload (`render.player: webgl`) | {payload:,} | three.js "
        f"{result['library'] / 1e6:.1f} MB + player {result['player_js'] / 1e3:.0f} KB | "
        f"{times['player']['cold']:.0f} | {times['player']['warm']:.0f} |",
        "",
        f"- A payload is {mp4 / payload:.0f}× smaller than the mp4 ({payload / 1e3:.1f} KB "
        f"against {mp4 / 1e3:.0f} KB; every clip of the same length has the same size; "
        f"{result['payload_gzip'] / 1e3:.1f} KB gzipped, a size that does depend on the "
        "content, so serve payloads uncompressed). three.js (unminified, as published) is "
        f"fetched once and then cached: {result['library_gzip'] / 1e3:.0f} KB gzipped.",
        f"- Of the player's time to first frame, loading and running three.js and the player "
        f"took {times['player']['ready_cold']:.0f} ms cold and "
        f"{times['player']['ready_warm']:.0f} ms warm; the rest is the payloads' fetch and "
        "the first draw, where software WebGL compiles the shaders on the CPU (this machine "
        "has no GPU, so the table shows the slow case).",
        "",
    ])


def write_docs(text: str) -> None:
    current = DOCS.read_text() if DOCS.exists() else "# Benchmarks\n"
    pattern = re.compile(rf"^{re.escape(HEADING)}\n.*?(?=^## |\Z)", re.M | re.S)
    if pattern.search(current):
        current = pattern.sub(lambda _: text + "\n", current)
    else:
        current = current.rstrip("\n") + "\n\n" + text + "\n"
    DOCS.write_text(current)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=480)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--write", action="store_true", help="update docs/BENCHMARKS.md")
    options = parser.parse_args()
    if not Path(CHROMIUM).exists():
        raise SystemExit(f"{CHROMIUM} is needed (make setup installs it as root)")
    text = section(measure(options.size, options.rounds))
    print(text)
    if options.write:
        write_docs(text)
        print(f"written to {DOCS.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
