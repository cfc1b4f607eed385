"""Screenshot the first trial page of every study, as a phone (390x844) shows it.

    make demo ARGS=--no-serve
    .venv/bin/python scripts/phone_screenshots.py docs/images/phone

Serves the site on a free local port, logs in as the demo's admin and walks each study's
staff preview (nothing is stored) to its first trial, waits until its clips have played,
and saves ``<out>/<study type>-screen.jpg`` (the first screen, as the phone shows it) and
``<out>/<study type>.jpg`` (the whole page, its submit bar at the end instead of fixed to
the bottom of the screen). Needs Debian's chromium.
"""

import argparse
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]
PLAYED = ("() => [...document.querySelectorAll('[data-required] [data-plays]')]"
          ".every(i => +i.value > 0)")


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="folder of the screenshots")
    parser.add_argument("--width", type=int, default=390)
    parser.add_argument("--height", type=int, default=844)
    options = parser.parse_args()
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "studyapp.settings")
    import django

    django.setup()
    from django.conf import settings
    from playwright.sync_api import sync_playwright

    from studyapp.survey.models import Study

    studies = list(Study.objects.order_by("study_type"))
    password = (Path(settings.VAR_DIR) / "demo" / "admin-password.txt").read_text().strip()
    port = free_port()
    server = subprocess.Popen([sys.executable, "manage.py", "runserver", f"127.0.0.1:{port}",
                               "--noreload"], cwd=ROOT, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    base = f"http://127.0.0.1:{port}"
    options.out.mkdir(parents=True, exist_ok=True)
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            context = browser.new_context(viewport={"width": options.width,
                                                    "height": options.height},
                                          device_scale_factor=2, is_mobile=True,
                                          has_touch=True)
            page = context.new_page()
            page.set_default_timeout(30_000)
            for _ in range(100):  # the server starts
                try:
                    page.goto(f"{base}/admin/login/")
                    break
                except Exception:
                    time.sleep(0.2)
            page.fill("#id_username", "admin")
            page.fill("#id_password", password)
            page.click("input[type=submit]")
            for study in studies:
                page.goto(f"{base}/preview/{study.slug}/")
                page.get_by_label("I have read the information above").check()
                page.get_by_role("button", name="Continue").click()
                page.get_by_role("button", name="Start").click()
                page.wait_for_selector("[data-trial-form][data-ready]", state="attached")
                page.wait_for_function(PLAYED)
                path = options.out / f"{study.study_type}.jpg"
                page.screenshot(path=str(options.out / f"{study.study_type}-screen.jpg"), quality=80)
                # The whole page: the submit bar (fixed to the screen's bottom) at its end.
                page.add_style_tag(content=".submit-bar { position: static; }")
                page.screenshot(path=str(path), full_page=True, quality=80)
                print(f"{study.slug}: {path}")
            browser.close()
    finally:
        server.terminate()
        server.wait(10)


if __name__ == "__main__":
    main()
