"""The blindness audit through HTTP: it fails deliberately leaky builds (sizes that follow
the source, deliveries with the same bytes, catch clips a payload script can pick out),
passes the demo, leaves no trace in the study, and `analyze` reports it."""

import json
from io import StringIO

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from studyapp.stimuli import media
from studyapp.survey.models import Participant, Trial, TrialItem
from studyapp.stimuli.clips import Clip
from tests.studyapp.conftest import FPS, FRAMES, make_study, write_clip, write_poster
from tests.studyapp.rendered_clips import render_clips

ACTIONS = [f"action{k}" for k in range(10)]


@pytest.fixture(scope="module")
def leaky_clips(tmp_path_factory):
    """Real clips encoded larger than generated ones: a build that leaks the source."""
    root = tmp_path_factory.mktemp("leaky")
    rng = np.random.default_rng(3)
    out = []
    for action in ACTIONS:
        for source in ("real", "a2m", "cond_gru"):
            size = 96 if source == "real" else 64
            colour = tuple(int(c) for c in rng.integers(30, 225, size=3))
            path = root / f"{action}-{source}.mp4"
            write_clip(path, colour, size=size)
            write_poster(path.with_suffix(".png"), colour, size=size)
            out.append(Clip(action, source, path, FRAMES / FPS, motion_hash=f"{action}-{source}",
                            poster=path.with_suffix(".png")))
    return out


def audit(study, url, tmp_path, level="deep"):
    out = tmp_path / f"audit-{study.slug}-{level}.json"
    text = StringIO()
    try:
        call_command("audit_blindness", study=study.slug, url=url, json_out=str(out),
                     level=level, stdout=text)
        error = None
    except CommandError as failure:
        error = str(failure)
    return json.loads(out.read_text()), text.getvalue(), error


@pytest.mark.django_db(transaction=True)
def test_a_leaky_build_fails_the_audit_through_http(leaky_clips, media_root, live_server,
                                                    tmp_path):
    study = make_study("ranking", leaky_clips, slug="leaky")
    for level in ("basic", "deep"):
        result, text, error = audit(study, live_server.url, tmp_path, level)
        source = result["source: delivery"]
        assert source["n"] == 30 and not source["passed"] and source["auc"] > 0.95
        assert source["p_value"] < 0.01 and source["says"].startswith("FAILED")
        assert "can be told apart by what is sent (source: delivery" in error
        assert "source: delivery: FAILED" in text
    assert set(result) == {"source: delivery", "source: bitstream", "catch: delivery",
                           "catch: bitstream", "deliveries: hashes", "deliveries: content"}
    # ffmpeg's own files have no filler to lay out anew: every delivery is the same bytes.
    assert not result["deliveries: hashes"]["passed"]
    # The audit's participants are gone again: nothing counts them, nothing exports them.
    assert not Participant.objects.exists() and not Trial.objects.exists()
    assert not TrialItem.objects.exists()


@pytest.fixture(scope="module")
def built_clips(tmp_path_factory):
    return render_clips(tmp_path_factory.mktemp("audited"), catch_per_action=3)


@pytest.mark.django_db(transaction=True)
def test_deliveries_with_the_same_bytes_fail_the_deep_audit(built_clips, media_root,
                                                            live_server, tmp_path, monkeypatch):
    study = make_study("ranking", built_clips, slug="own-bytes", catch_trials=1)
    result, text, error = audit(study, live_server.url, tmp_path)
    hashes = result["deliveries: hashes"]
    assert hashes["passed"] and hashes["n"] == 2 * len(built_clips)
    content = result["deliveries: content"]
    assert content["same_clip_alike"] == content["n"] == 3 * len(built_clips)
    assert content["different_clips_alike"] == 0 and content["catch_clips"] == 6
    # The leaky server: every delivery the stored bytes, as before per-delivery bytes.
    monkeypatch.setattr(media, "delivered_bytes", lambda data, *args, **kwargs: data)
    result, text, error = audit(study, live_server.url, tmp_path)
    hashes = result["deliveries: hashes"]
    assert not hashes["passed"] and hashes["repeated_bytes"] == 3 * len(built_clips)
    assert "deliveries: hashes" in error and "recognises a repeated trial's clip" in text


@pytest.mark.django_db
def test_the_in_process_audit_reads_the_delivery_bytes_behind_nginx(built_clips, media_root,
                                                                     settings):
    """With STUDY_ACCEL_REDIRECT the clip view answers with an empty body for nginx; the
    audit without a server (``arena add``, ``analyze``) still compares the bytes each
    delivery carries, and writes no delivery file doing so."""
    from studyapp.results.audit import audit_study, view_fetcher

    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"
    study = make_study("ranking", built_clips, slug="behind-nginx", catch_trials=1)
    result = audit_study(study, view_fetcher(), "deep")
    hashes = result["deliveries: hashes"]
    assert hashes["passed"] and hashes["n"] == 2 * len(built_clips)
    assert not (media_root / "deliveries").exists()


@pytest.mark.django_db
def test_analyze_reports_the_audit(leaky_clips, media_root, make_bot, tmp_path):
    study = make_study("ranking", leaky_clips, slug="leaky-report", trials_per_participant=2)
    for _ in range(2):
        bot = make_bot(study)
        bot.join()
        bot.finish()
    err = StringIO()
    call_command("analyze", study=study.slug, out=str(tmp_path / "report"), no_exclusions=True,
                 stdout=StringIO(), stderr=err)
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert summary["blindness"]["source: delivery"]["passed"] is False
    assert summary["blindness"]["source: bitstream"]["kind"] == "content"
    assert (tmp_path / "report" / "blindness.csv").is_file()
    assert "Blindness audit: source: delivery can be told apart" in err.getvalue()
    assert Participant.objects.count() == 2  # only the real ones


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_the_demo_passes_the_deep_audit_and_shaken_catch_clips_fail_it(
        media_root, live_server, tmp_path, monkeypatch):
    from motion import perturb
    from studyapp.stimuli.management.commands.demo import DEMO_CONFIGS
    from studyapp.stimuli.build import build_stimuli
    from studyapp.stimuli.config import load_config

    # The demo's ranking study, every action, small, played in the page: 48 judged clips
    # and 48 catch clips (two broken versions of a clip of each source, per action).
    overrides = ["render.size=64", "render.player=webgl"]
    config = load_config(DEMO_CONFIGS / "ranking.yaml", overrides)
    study = build_stimuli(config, tmp_path / "b", cache=tmp_path / "cache").study
    result, text, error = audit(study, live_server.url, tmp_path)
    assert error is None, text
    assert result["source: delivery"]["n"] == 48 and result["catch: delivery"]["n"] == 96
    assert set(result) >= {"source: payload", "catch: payload"}
    assert result["source: payload"]["kind"] == "content"  # the motion itself: told, not failed
    # The attack of before: catch clips shaken, bones stretching; the payload tells them.
    monkeypatch.setattr(perturb, "catch_candidates", lambda bases, per, rng, *a, **k: [
        [perturb.jitter(m, 0.25, rng, "broken") for _ in range(per)] for m in bases])
    config = load_config(DEMO_CONFIGS / "ranking.yaml", overrides + ["slug=shaken"])
    shaken = build_stimuli(config, tmp_path / "b2", cache=tmp_path / "cache").study
    result, text, error = audit(shaken, live_server.url, tmp_path)
    catch = result["catch: payload"]
    assert not catch["passed"] and catch["auc"] > 0.95
    assert "pass attention checks without watching" in catch["says"]
