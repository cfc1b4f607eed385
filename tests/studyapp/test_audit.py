"""The blindness audit through HTTP: it fails on a deliberately leaky build, leaves no
trace in the study, and `analyze` reports it."""

import json
from io import StringIO

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from studyapp.survey.models import Participant, Trial, TrialItem
from studyapp.survey.stimuli import Clip
from tests.studyapp.conftest import FPS, FRAMES, make_study, write_clip, write_poster

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


@pytest.mark.django_db(transaction=True)
def test_a_leaky_build_fails_the_audit_through_http(leaky_clips, media_root, live_server,
                                                    tmp_path):
    study = make_study("ranking", leaky_clips, slug="leaky")
    out = tmp_path / "audit.json"
    text = StringIO()
    with pytest.raises(CommandError, match="can be told apart"):
        call_command("audit_blindness", study=study.slug, url=live_server.url,
                     json_out=str(out), stdout=text)
    result = json.loads(out.read_text())
    assert set(result) == {"source", "catch"}
    assert result["source"]["n"] == 30 and not result["source"]["passed"]
    assert result["source"]["accuracy"] > 0.9 and result["source"]["chance"] == pytest.approx(2 / 3)
    assert "source: accuracy" in text.getvalue() and "FAILED" in text.getvalue()
    # The audit's participant is gone again: nothing counts it, nothing exports it.
    assert not Participant.objects.exists() and not Trial.objects.exists()
    assert not TrialItem.objects.exists()


@pytest.mark.django_db
def test_analyze_reports_the_audit(leaky_clips, media_root, make_bot, tmp_path):
    study = make_study("ranking", leaky_clips, slug="leaky-report", trials_per_participant=2)
    bot = make_bot(study)
    bot.join()
    bot.finish()
    second = make_bot(study)
    second.join()
    second.finish()
    err = StringIO()
    call_command("analyze", study=study.slug, out=str(tmp_path / "report"), no_exclusions=True,
                 stdout=StringIO(),
                 stderr=err)
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert summary["blindness"]["source"]["passed"] is False
    assert (tmp_path / "report" / "blindness.csv").is_file()
    assert "Blindness audit: source can be told apart" in err.getvalue()
    assert Participant.objects.count() == 2  # only the real ones


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_the_demo_passes_the_audit_through_http(media_root, live_server, tmp_path):
    from studyapp.survey.management.commands.demo import DEMO_CONFIGS
    from studyapp.survey.stimulus_build import build_stimuli
    from studyapp.survey.stimulus_config import load_config

    # The demo's ranking study, every action, at a small size: 48 judged and 8 catch clips.
    config = load_config(DEMO_CONFIGS / "ranking.yaml", ["render.size=96"])
    study = build_stimuli(config, tmp_path / "b", cache=tmp_path / "cache").study
    out = tmp_path / "audit.json"
    call_command("audit_blindness", study=study.slug, url=live_server.url, json_out=str(out),
                 stdout=StringIO())
    result = json.loads(out.read_text())
    assert result["source"]["n"] == 48 and result["source"]["passed"]
    assert result["catch"]["n"] == 56 and result["catch"]["passed"]
