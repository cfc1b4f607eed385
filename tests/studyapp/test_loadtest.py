"""The load test's own machinery at a tiny scale: the arrival curve, and a launch of a
few participants on the in-page player's clips against a real gunicorn and PostgreSQL."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.loadtest import arrival_times

ROOT = Path(__file__).resolve().parents[2]


def test_arrivals_come_front_loaded_within_the_window_and_repeat_with_the_seed():
    times = arrival_times(2000, 300.0, seed=3)
    assert times == sorted(times) and 0 <= times[0] and times[-1] <= 300
    assert times == arrival_times(2000, 300.0, seed=3)
    first_half = sum(t < 150 for t in times) / len(times)
    assert 0.70 < first_half < 0.80  # density 2(1 - t/T)/T: three quarters in the first half


@pytest.mark.slow
def test_a_tiny_launch_reports_answers_and_clip_fetches_apart_and_loses_nothing(tmp_path):
    run = subprocess.run(
        [sys.executable, "benchmarks/loadtest.py", "--arrivals", "4", "--over", "1",
         "--trials", "2", "--workers", "2", "--study", "webgl", "--time-limit", "120"],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    figures = dict(re.findall(r"(\w+)=(\S+)", run.stdout))
    assert figures["study"] == "webgl" and figures["arrivals"] == "4"
    assert figures["acknowledged"] == figures["stored"] == "8"
    assert figures["duplicates"] == "0" and figures["missing"] == "0"
    # Each first answer brings the next trial; the last one redirects to the end.
    assert figures["answers_with_the_next_trial"] == "4/8"
    assert figures["clip_fetches"] == str(4 * 2 * 3)  # the motion payloads, each whole
    for name in ("answer_p99_ms", "clip_ttfb_p99_ms"):
        assert float(figures[name]) > 0


@pytest.mark.slow
def test_a_tiny_launch_behind_nginx_takes_every_answer_from_its_log(tmp_path):
    """As `make serve` runs: clips written ahead by their pages, sent by nginx, watched
    as its log says (follow_fetches); every answer taken, nothing lost."""
    from benchmarks.server import NGINX
    from tests.studyapp.conftest import require_service

    require_service(Path(NGINX).exists(), f"nginx ({NGINX})")
    run = subprocess.run(
        [sys.executable, "benchmarks/loadtest.py", "--arrivals", "4", "--over", "1",
         "--trials", "2", "--workers", "2", "--study", "webgl", "--time-limit", "120", "--nginx"],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    figures = dict(re.findall(r"(\w+)=(\S+)", run.stdout))
    assert "behind nginx" in run.stdout
    assert figures["acknowledged"] == figures["stored"] == "8" and figures["errors"] == "0"
    assert figures["clip_fetches"] == str(4 * 2 * 3)


def test_the_answers_latency_is_split_by_when_they_went_and_the_window_must_be_positive():
    import argparse
    from types import SimpleNamespace

    import pytest

    from benchmarks.loadtest import positive_seconds, windows

    bots = [SimpleNamespace(answer_at=[100.0, 131.0], answer_seconds=[0.010, 0.200]),
            SimpleNamespace(answer_at=[105.0], answer_seconds=[0.030])]
    text = windows(bots, launch=100.0, width=30.0)
    assert text.startswith("0-30: ") and "(2)" in text and text.endswith("30-60: 200/200 (1)")
    with pytest.raises(argparse.ArgumentTypeError, match="above 0"):
        positive_seconds("0")
