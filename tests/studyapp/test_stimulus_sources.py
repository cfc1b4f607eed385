"""The training path of a build's method sources: schedules, training seeds, metrics, reports."""

import itertools
import json
from pathlib import Path

import pandas as pd
import pytest
import torch
from django.core.management import call_command

from motion.datasets import get_dataset
from generation.methods import load_checkpoint
from generation.methods.budget import train_within_budget
from motion_metrics.recognition import Split, one_thread
from motion_metrics.comparison import H36M_TEST, H36M_TRAIN, recipe_for
from studyapp.results.export import responses_frame
from studyapp.stimuli.build import Build, build_stimuli
from studyapp.stimuli.config import ConfigError, parse
from studyapp.stimuli.sources import sources_sentences, sources_table

ROOT = Path(__file__).resolve().parents[2]


def config(**changes) -> dict:
    raw = {
        "slug": "seeds-ranking", "title": "Which looks best?", "seed": 0, "dataset": "demo",
        "actions": ["walk", "wave"], "frames": 12, "clips_per_source": 3,
        "train": {"iters": 4, "preset": "tiny", "schedule": "benchmark", "seeds": [0, 1]},
        "metrics": {"train_classifier": True, "classifier_preset": "tiny", "classifier_iters": 10,
                    "n": 3, "repeats": 2},
        "sources": ["real", "cond_gru", "skeleton_gan"],
        "render": {"style": "stick", "size": 64},
        "study": {"type": "ranking"},
    }
    raw.update(changes)
    return raw


@pytest.mark.parametrize("changes, words", [
    ({"train": {"iters": 2000, "preset": "paper"}, "sources": ["real", "c_skeleton_gan"]},
     ["sources.1.iters (or train.iters)", "pretrains its frame decoder", "first 10,000 iterations",
      "pretrain_iters of the paper preset", "2,000 iterations end inside", "schedule: benchmark"]),
    ({"train": {"schedule": "quick"}}, ["train.schedule", "'quick'", "benchmark", "full"]),
    ({"train": {"seeds": [0, 0]}}, ["train.seeds", "names a seed twice"]),
    ({"train": {"seeds": "one"}}, ["train.seeds", "list of whole numbers"]),
    ({"train": {"epochs": 3}}, ["train.epochs", "iters, preset, schedule, seeds"]),
    ({"sources": [{"method": "a2m", "checkpoint": "x.pt", "seeds": [1, 2]}]},
     ["sources.0.seeds", "has that checkpoint's training seed"]),
    ({"metrics": {"n": 1}}, ["metrics.n", "at least 2"]),
    ({"sources": [{"method": "sa_gcn", "config": {"he": True}}]},
     ["sources.0.config", "sa_gcn has no config field 'he'", "qk_norm"]),
    ({"sources": [{"method": "sa_gcn", "config": {"init": 1}}]},
     ["sources.0.config", "init: 1 must be a str"]),
    ({"sources": [{"method": "sa_gcn", "config": {"init": "he"}, "checkpoint": "x.pt"}]},
     ["sources.0.config", "has that checkpoint's config"]),
    ({"metrics": {"mmd_protocol": "mine"}}, ["metrics.mmd_protocol", "'mine'", "heldout"]),
    ({"metrics": {"classifier_preset": "huge"}}, ["metrics.classifier_preset", "augmented"]),
    ({"metrics": "yes"}, ["metrics", "false to measure nothing"]),
])
def test_training_and_metrics_fields_are_checked(tmp_path, changes, words):
    with pytest.raises(ConfigError) as error:
        parse(config(**changes), tmp_path)
    for word in words:
        assert word in str(error.value)


def test_a_source_sets_config_fields_and_the_manifest_names_its_departures(tmp_path):
    """sa_gcn as published (paper preset) with one departure turned on by the config; the
    recipe, cache key, manifest and report sentence carry it."""
    from studyapp.stimuli.sources import MethodSources

    raw = config(sources=["real", {"method": "sa_gcn", "name": "sa_gcn_eq1", "preset": "tiny",
                                   "config": {"init": "default", "mismatch_weight": 0}}])
    source = parse(raw, tmp_path).sources[1]
    assert source.changes == {"init": "default", "mismatch_weight": 0.0}
    build = Build(parse(raw, tmp_path), tmp_path / "build", cache=tmp_path / "cache")
    methods = MethodSources(build)
    assert methods.recipe(source).describe() == "tiny (init=default, mismatch_weight=0.0)"
    assert "mismatch_weight" not in methods.departures(source)
    assert methods.departures(source)["qk_norm"] is True  # still on in the tiny preset
    plain = parse(config(sources=["real", {"method": "sa_gcn", "name": "sa_gcn_eq1",
                                           "preset": "tiny"}]), tmp_path).sources[1]
    assert methods.folder(plain) != methods.folder(source)  # another config, another cache
    said = sources_sentences({"sources": [{
        "source": "sa_gcn_eq1", "preset": "tiny", "schedule": "benchmark",
        "config": source.changes, "departures": methods.departures(source),
        "checkpoints": [{"training_seed": 0, "checkpoint": "ab" * 32, "iterations": 4,
                         "given": False, "phases": None, "metrics": None}]}]})
    assert said == ["Clips of sa_gcn_eq1 come from a checkpoint trained 4 iterations with training "
                    "seed 0 (sha256 abababababab; tiny preset, benchmark schedule, with "
                    "init=default, mismatch_weight=0.0; departures from the paper: qk_norm=True, "
                    "gated_residual=True, self_loop=True): no metrics measured at build time"]


def test_a_budget_past_the_pretraining_stage_trains_in_full(tmp_path):
    parsed = parse(config(train={"iters": 12_000, "preset": "paper"},
                          sources=["real", "c_skeleton_gan"]), tmp_path)
    assert parsed.sources[1].schedule == "full" and parsed.sources[1].seeds is None
    assert parse(config(metrics=False), tmp_path).metrics.enabled is False


@pytest.mark.django_db
def test_clips_come_from_every_training_seed_in_turn_and_carry_it(tmp_path, media_root):
    """A source with seeds trains one checkpoint per seed; clip i of an action comes from
    seed i mod S; each stimulus keeps its checkpoint's sha256 and training seed, the export
    has them as columns, and the manifest lists every checkpoint with its budget and metrics."""
    result = build_stimuli(parse(config(), tmp_path), tmp_path / "build", cache=tmp_path / "cache")
    study = result.study
    judged = study.stimuli.judged().filter(source="skeleton_gan").order_by("id")
    assert list(judged.values_list("training_seed", flat=True)) == [0, 1, 0, 0, 1, 0]
    assert len(set(judged.values_list("checkpoint", flat=True))) == 2
    assert not study.stimuli.filter(source="real").exclude(checkpoint="").exists()

    manifest = json.loads((tmp_path / "build" / "manifest.json").read_text())
    by_seed = {c["training_seed"]: c for c in manifest["sources"][1]["checkpoints"]}
    assert manifest["sources"][1]["source"] == "skeleton_gan" and set(by_seed) == {0, 1}
    folder = next((tmp_path / "cache" / "checkpoints").glob("skeleton_gan-*"))
    for seed, entry in by_seed.items():
        checkpoint = load_checkpoint(folder / f"skeleton_gan-seed{seed}.pt")
        assert checkpoint.seed == seed and checkpoint.iteration == entry["iterations"] == 4
        assert entry["recipe"].startswith("tiny") and manifest["sources"][1]["schedule"] == "benchmark"
        first, rest = entry["phases"]  # the benchmark schedule: half the budget pretrains
        assert first["phase"] == "pretrain_iters" and first["iterations"] + rest["iterations"] == 4
        measured = entry["metrics"]["metrics"]
        assert {"fid", "accuracy", "diversity", "mmd_avg", "mmd_seq", "n_apd"} <= set(measured)
        assert measured["n_apd"]["real"]["mean"] > 0
        assert entry["metrics"]["held_out_trained_on"]  # the demo data has no subjects
    assert manifest["metrics"]["classifier"]["test_accuracy"] is not None
    clips = [c for c in manifest["clips"] if c["source"] == "skeleton_gan"]
    assert [c["training_seed"] for c in clips] == [0, 1, 0, 0, 1, 0]
    assert {c["checkpoint"] for c in clips} == {by_seed[0]["checkpoint"], by_seed[1]["checkpoint"]}

    table = sources_table(manifest)
    assert list(table["source"]) == ["Real (held-out vs training clips)", "cond_gru", "cond_gru",
                                     "skeleton_gan", "skeleton_gan"]
    assert {"FID", "MMD_avg", "n-APD", "checkpoint", "training seed", "phases"} <= set(table.columns)
    said = sources_sentences(manifest)
    assert said[1].startswith("Clips of skeleton_gan come from 2 checkpoints in turn (tiny preset, "
                              "benchmark schedule): one trained 4 iterations with training seed 0 "
                              f"(sha256 {by_seed[0]['checkpoint'][:12]}; it pretrains its single-pose GAN "
                              f"for the first {by_seed[0]['phases'][0]['iterations']})")
    assert "FID " in said[1] and "accuracy " in said[1] and "with training seed 1" in said[1]
    assert manifest["sources"][0]["checkpoints"][0]["phases"] is None  # cond_gru has no phases

    again = build_stimuli(parse(config(), tmp_path), tmp_path / "build", cache=tmp_path / "cache")
    assert again.unchanged and again.sampled == []  # checkpoints and metrics are reused


@pytest.mark.django_db
def test_the_report_shows_the_checkpoints_beside_the_human_scores(tmp_path, media_root,
                                                                   make_bot, settings,
                                                                   monkeypatch):
    settings.VAR_DIR = tmp_path / "var"
    # Participants' plans come from random seeds: a few participants could be shown clips
    # of one training seed only, and then no seed is redrawn. Seeds 1, 2, ... instead.
    seeds = itertools.count(1)
    monkeypatch.setattr("studyapp.survey.models.participation.secrets.randbits",
                        lambda bits: next(seeds))
    raw = config(train={"iters": 4, "preset": "tiny", "seeds": [0, 1]},
                 sources=["real", "cond_gru"], study={"type": "ranking", "practice": False})
    result = build_stimuli(parse(raw, tmp_path), tmp_path / "var" / "stimuli" / "seeds-ranking",
                           cache=tmp_path / "cache")
    for _ in range(4):
        bot = make_bot(result.study)
        bot.join()
        bot.finish()
    table = responses_frame(result.study)
    method = table[table["source"] == "cond_gru"]
    assert set(method["training_seed"].dropna()) <= {0, 1} and method["checkpoint"].str.len().min() == 64
    assert table.loc[table["source"] == "real", "training_seed"].isna().all()
    out = tmp_path / "report"
    call_command("analyze", "--study", "seeds-ranking", "--out", str(out), "--no-audit", "--no-exclusions",
                 "--bootstrap", "20")
    page = (out / "report.html").read_text()
    assert "Stimulus sources" in page and "classifier held-out accuracy" in page
    # The methods paragraph says which checkpoints the clips come from, with their metrics.
    assert "Clips of cond_gru come from 2 checkpoints in turn (tiny preset, " in page
    assert "with training seed 1 (sha256 " in page
    # The export's training seeds reach the crossed inference: seeds are redrawn whole.
    assert "for the source whose clips come from several training seeds (2 each)" in page
    sources = pd.read_csv(out / "stimulus_sources.csv")
    assert list(sources["source"])[1:] == ["cond_gru", "cond_gru"]
    assert sorted(sources["training seed"].dropna()) == [0, 1]


def test_a_build_trains_the_checkpoint_benchmark_methods_trains(tmp_path, h36m_root):
    """The same method, preset, schedule, budget, seed and training subjects give the same
    weights in a build as in compare_methods (one training loop)."""
    raw = config(dataset="h36m2d", data_root=str(h36m_root), actions=None, frames=None,
                 subjects=list(H36M_TRAIN), sources=["skeleton_gan"],
                 train={"iters": 4, "preset": "tiny", "schedule": "benchmark", "seeds": [1]})
    build = Build(parse(raw, tmp_path), tmp_path / "build", cache=tmp_path / "cache")
    trained = build.methods.trained(build.config.sources[0])
    data = get_dataset("h36m2d", h36m_root)
    train, _ = Split(test_subjects=H36M_TEST, train_subjects=H36M_TRAIN).divide(data.clips())
    assert len(train) == len(build.dataset.clips(subjects=list(H36M_TRAIN)))
    with one_thread():  # as run_comparison trains
        benchmark, _ = train_within_budget("skeleton_gan", train, data.actions(), None,
                                           tmp_path / "benchmark",
                                           recipe_for("skeleton_gan", {"skeleton_gan": "tiny"}, 4),
                                           seed=1, iters=4)
    built = load_checkpoint(trained[0].path)
    for key, net in benchmark.networks.items():
        for (name, a), b in zip(net.state_dict().items(), built.networks[key].state_dict().values()):
            assert torch.equal(a, b), (key, name)
