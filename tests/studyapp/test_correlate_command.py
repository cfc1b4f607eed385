"""correlate: a real study built from the demo's checkpoints, answered through its pages,
its human scores beside the objective metrics of the very motions it showed."""

import itertools
import json

import numpy as np
import pandas as pd
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from motion_metrics.recognition import train_classifier
from studyapp.survey.models import Study
from studyapp.stimuli.build import build_stimuli
from studyapp.stimuli.config import parse
from tests.conftest import ROOT

CHECKPOINTS = ROOT / "studies" / "demo" / "checkpoints"
FRAMES = 12
# What the simulated participants prefer (log strengths): best first.
STRENGTHS = {"real": 3.0, "a2m": 2.0, "a2m_s7": 1.0, "cond_gru": 0.0, "skeleton_vae": -1.0}


def config(tmp_path):
    """Return a small ranking study of real clips and four method sources sampled from the
    demo's shipped checkpoints (a2m twice, two seeds) and one trained for 2 iterations:
    2 actions, 3 clips per source, 64 px."""
    method = lambda key, **more: {"method": key, "checkpoint": str(CHECKPOINTS / f"{key}.pt"), **more}
    return parse({
        "slug": "corr-ranking", "title": "Which looks best?", "seed": 0, "dataset": "demo",
        "actions": ["walk", "wave"], "frames": FRAMES, "clips_per_source": 3,
        "sources": ["real", method("a2m"), method("cond_gru"),
                    method("a2m", name="a2m_s7", seed=7),
                    "skeleton_vae"],
        "train": {"iters": 2, "preset": "tiny"},
        "render": {"style": "stick", "size": 64},
        "study": {"type": "ranking", "clips_per_trial": 5},
    }, tmp_path)


def answer_all(make_bot, study, n, seed=0):
    """Let ``n`` participants rank every trial by :data:`STRENGTHS` plus Gumbel noise."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        bot = make_bot(study)
        bot.join()
        while (trial := bot.participant().current_trial()) is not None:
            items = list(trial.items.select_related("stimulus").order_by("position"))
            utility = {item.position: STRENGTHS.get(item.stimulus.source, -5.0) + rng.gumbel()
                       for item in items if item.role == "judged"}
            order = sorted(utility, key=utility.get, reverse=True)
            bot.trial_page()
            bot.answer(bot.answer_data(trial, ranks={pos: k + 1 for k, pos in enumerate(order)}),
                       follow=True)


@pytest.mark.django_db
def test_correlate_a_built_and_answered_study(tmp_path, media_root, make_bot, settings, capsys,
                                              monkeypatch):
    settings.VAR_DIR = tmp_path / "var"  # the build's default folders
    stimuli = settings.VAR_DIR / "stimuli"
    build_stimuli(config(tmp_path), stimuli / "corr-ranking", cache=stimuli / "cache")
    study = Study.objects.get(slug="corr-ranking")
    out = tmp_path / "report"

    with pytest.raises(CommandError, match="no answers yet; collect answers"):
        call_command("correlate", study=study.slug, out=str(out))
    # Each participant's trial plan comes from a random seed; with six of them the order of
    # the two lowest sources would differ from run to run. Seeds 1, 2, ... instead.
    seeds = itertools.count(1)
    monkeypatch.setattr("studyapp.survey.models.participation.secrets.randbits", lambda bits: next(seeds))
    answer_all(make_bot, study, 6)

    classifier = tmp_path / "classifier.pt"
    with pytest.raises(CommandError, match=r"No classifier at --classifier .*classifier.pt; "
                                           r"train one: manage.py train_classifier --dataset demo"):
        call_command("correlate", study=study.slug, out=str(out), classifier=str(classifier))
    train_classifier("demo", classifier, actions="walk,wave", frames=FRAMES, iters=5,
                     preset="tiny", progress=False)

    call_command("correlate", study=study.slug, out=str(out), classifier=str(classifier),
                 bootstrap=20, min_time_factor=0, shown_clips=True)
    printed = capsys.readouterr()
    assert "Study corr-ranking: 4 methods" in printed.out
    assert "real (real clips) is not a method" in printed.err
    assert "fewer than 4 sources" not in printed.err
    table = pd.read_csv(out / "correlations.csv").set_index("metric")
    assert list(table.index) == ["fid", "accuracy", "diversity", "multimodality", "mmd_avg",
                                 "mmd_seq", "apd"]
    assert table.loc["fid", "direction"] == "lower is better"
    assert table["n_sources"].eq(4).all()
    finite = table["kendall"].dropna()
    assert len(finite) >= 5 and finite.between(-1, 1).all()
    assert (table["kendall_low"] <= table["kendall_high"]).all()
    sources = pd.read_csv(out / "sources.csv").set_index("source")
    assert set(sources.index) == {"a2m", "cond_gru", "a2m_s7", "skeleton_vae"}
    # The preference the participants followed comes back as the human score's order.
    assert sources["score"].idxmax() == "a2m" and sources["score"].idxmin() == "skeleton_vae"
    for name in ("report.html", "correlations.md", "scatter_fid.png", "scatter_fid.svg",
                 "scatter_mmd_seq.png"):
        assert (out / name).is_file(), name
    page = (out / "report.html").read_text()
    assert "Spearman" in page and "Too few sources" not in page and "Plackett-Luce" in page


@pytest.mark.django_db
def test_missing_motions_and_no_methods_name_the_fix(tmp_path, media_root, make_bot, settings,
                                                     capsys):
    folder = tmp_path / "build"  # built with --out: manifest and cache there
    build_stimuli(config(tmp_path), folder)
    study = Study.objects.get(slug="corr-ranking")
    answer_all(make_bot, study, 2)
    out = str(tmp_path / "report")
    settings.VAR_DIR = tmp_path / "elsewhere"
    with pytest.raises(CommandError, match="no build manifest at .*; rebuild it with "
                                           "`manage.py build_stimuli CONFIG`.*--manifest"):
        call_command("correlate", study=study.slug, out=out)

    empty = tmp_path / "empty-cache"
    (empty / "motions").mkdir(parents=True)
    with pytest.raises(CommandError, match="source 'a2m': 6 of the 6 motions study 'corr-ranking' "
                                           "showed are not in the build cache"):
        call_command("correlate", study=study.slug, out=out,
                     manifest=str(folder / "manifest.json"), cache=str(empty))

    # Only two methods (the others' clips dropped from the manifest): too few, and said so.
    manifest = json.loads((folder / "manifest.json").read_text())
    for entry in manifest["clips"]:
        if entry["source"] in ("a2m_s7", "skeleton_vae"):
            entry.pop("checkpoint")
    (folder / "few.json").write_text(json.dumps(manifest))
    call_command("correlate", study=study.slug, out=out, manifest=str(folder / "few.json"),
                 cache=str(folder), bootstrap=0, min_time_factor=0)
    err = capsys.readouterr().err
    assert "only 2 method(s): a rank correlation over fewer than 4 sources" in err
    assert "Too few sources" in (tmp_path / "report" / "report.html").read_text()
    assert "fid skipped: needs an action classifier (pass --classifier)" in err

    for entry in manifest["clips"]:
        entry.pop("checkpoint", None)
    (folder / "real.json").write_text(json.dumps(manifest))
    with pytest.raises(CommandError, match="has no method sources .*build a study whose sources "
                                           "are methods"):
        call_command("correlate", study=study.slug, out=out, manifest=str(folder / "real.json"))


def small_config(tmp_path):
    """Return a ranking study of real clips, three sources from the demo's shipped
    checkpoints (a2m twice, two seeds) and one file of 10 scaled real clips: 2 actions, 2
    clips per source, 48 px."""
    from generation.sampling import sample_real
    from motion.datasets import get_dataset
    from motion.formats import npz

    real = sample_real(get_dataset("demo"), ["walk", "wave"], 5, FRAMES, seed=4)
    npz.save(tmp_path / "ext.npz", [m.with_joints(m.joints * np.float32(0.9), source="x", meta={})
                                    for m in real])
    method = lambda key, **more: {"method": key, "checkpoint": str(CHECKPOINTS / f"{key}.pt"), **more}
    return parse({
        "slug": "corr-fresh", "title": "Which looks best?", "seed": 0, "dataset": "demo",
        "actions": ["walk", "wave"], "frames": FRAMES, "clips_per_source": 2,
        "sources": ["real", method("a2m"), method("cond_gru"), method("a2m", name="a2m_s7", seed=7),
                    {"name": "scaled", "file": "ext.npz"}],
        "render": {"style": "stick", "size": 48},
        "study": {"type": "ranking", "clips_per_trial": 5},
    }, tmp_path)


@pytest.mark.django_db
def test_correlate_measures_a_fresh_sample_from_each_checkpoint(tmp_path, media_root, make_bot,
                                                                settings, capsys):
    settings.VAR_DIR = tmp_path / "var"
    stimuli = settings.VAR_DIR / "stimuli"
    build_stimuli(small_config(tmp_path), stimuli / "corr-fresh", cache=stimuli / "cache")
    study = Study.objects.get(slug="corr-fresh")
    answer_all(make_bot, study, 3)
    out = tmp_path / "fresh"
    given = [f"a2m={CHECKPOINTS / 'a2m.pt'}", f"cond_gru={CHECKPOINTS / 'cond_gru.pt'}",
             f"a2m_s7={CHECKPOINTS / 'a2m.pt'}"]
    call_command("correlate", study=study.slug, out=str(out), bootstrap=0, min_time_factor=0,
                 fresh=30, source=given + [f"scaled={tmp_path / 'ext.npz'}"])
    printed = capsys.readouterr()
    assert f"(metrics on all 10 motions of its file {tmp_path / 'ext.npz'})" in printed.out
    assert "(metrics on 30 fresh motions from its checkpoint (a2m.pt; seed 7919, 2 actions))" in printed.out
    assert "(metrics on 30 fresh motions from its checkpoint (cond_gru.pt;" in printed.out
    sources = pd.read_csv(out / "sources.csv").set_index("source")
    assert sources["metrics_sample"].drop("scaled").str.startswith("30 fresh motions").all()
    assert "a2m: 30 fresh motions from its checkpoint" in (out / "report.html").read_text()
    fresh = sources["mmd_avg"]

    # The clips shown instead (4 per method): said so, and other numbers.
    call_command("correlate", study=study.slug, out=str(out), bootstrap=0, min_time_factor=0,
                 shown_clips=True)
    printed = capsys.readouterr()
    assert "(metrics on the 4 clips the study showed)" in printed.out
    assert "scaled: metrics on" not in printed.err
    shown = pd.read_csv(out / "sources.csv").set_index("source")
    assert not np.allclose(shown["mmd_avg"], fresh.loc[shown.index])

    # A checkpoint the config gave by path is not in the cache: the clips shown, with a note
    # naming the fix; a wrong file for a source is refused.
    call_command("correlate", study=study.slug, out=str(out), bootstrap=0, min_time_factor=0,
                 fresh=30, source=given[:1])
    err = capsys.readouterr().err
    assert "cond_gru: metrics on the 4 clips the study showed, not a fresh sample" in err
    assert "--source cond_gru=PATH" in err and "a2m:" not in err.replace("a2m_s7:", "")
    assert "scaled: metrics on the 4 clips the study showed: pass --source scaled=FILE" in err
    with pytest.raises(CommandError, match="--source cond_gru=.*a2m.pt is not the checkpoint"):
        call_command("correlate", study=study.slug, out=str(out), bootstrap=0,
                     source=[f"cond_gru={CHECKPOINTS / 'a2m.pt'}"])
    with pytest.raises(CommandError, match="--source scaled=.*a2m.pt is not the file the build read"):
        call_command("correlate", study=study.slug, out=str(out), bootstrap=0, min_time_factor=0,
                     fresh=30, source=[f"scaled={CHECKPOINTS / 'a2m.pt'}"])
