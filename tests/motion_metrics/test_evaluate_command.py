"""The train_classifier and evaluate commands on the demo dataset, and their errors."""

import io
import json

import numpy as np
import pytest
import torch
from django.core.management import CommandError, call_command

from motion.datasets import get_dataset
from motion.formats import npz
from generation.methods import get_method
from motion_metrics.recognition import ActionClassifier
from generation.sampling import sample_real
from motion_metrics.evaluate import METRICS
from tests.conftest import make_motion

torch.set_num_threads(1)

FRAMES = 20


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("evaluate")


@pytest.fixture(scope="module")
def trained(workdir):
    """Return the checkpoint of a tiny classifier trained by the command, and what it printed."""
    path, output = workdir / "clf.pt", io.StringIO()
    call_command("train_classifier", "--dataset", "demo", "--frames", str(FRAMES), "--iters", "10",
                 "--preset", "tiny", "--out", str(path), stdout=output, verbosity=0)
    return path, output.getvalue()


@pytest.fixture(scope="module")
def classifier(trained):
    return trained[0]


def write_motions(path, motions, **extras):
    """Write an interchange file, with optional per-motion arrays beside the required ones."""
    npz.save(path, motions)
    if extras:
        with np.load(path) as data:
            arrays = {key: data[key] for key in data.files}
        np.savez_compressed(path, **arrays, **extras)
    return path


@pytest.fixture(scope="module")
def real_motions(workdir):
    motions = sample_real(get_dataset("demo"), None, 3, frames=FRAMES, seed=1)
    rng = np.random.default_rng(0)
    return write_motions(workdir / "real.npz", motions, end_targets=rng.normal(size=(len(motions), 3)))


@pytest.fixture(scope="module")
def odmo_checkpoint(workdir):
    """Return a tiny ODMO checkpoint of every demo action, whose modes group real clips."""
    data = get_dataset("demo")
    cls = get_method("odmo")
    model = cls(cls.Config.preset("tiny"), data.skeleton, data.actions(), 25.0, FRAMES)
    model.fit(data.clips(frames=FRAMES, max_per_take=2), 5, progress=False)
    return model.save(workdir / "odmo.pt")


def test_train_classifier_reports_and_stores_held_out_accuracy(trained):
    path, printed = trained
    model = ActionClassifier.load(path)
    assert model.frames == FRAMES and model.dataset == "demo"
    assert model.test_accuracy is not None and model.n_test > 0
    assert f"test accuracy {model.test_accuracy:.3f} on {model.n_test} held-out clips" in printed
    assert f"kept iteration {model.best_iteration}: validation accuracy" in printed
    assert "held-out confusion matrix" in printed and model.confusion_text() in printed
    assert sum(map(sum, model.test_confusion)) == model.n_test


def test_evaluate_writes_every_metric_with_mean_and_ci(classifier, real_motions, odmo_checkpoint,
                                                       workdir, capsys):
    out = workdir / "result.json"
    call_command("evaluate", "--dataset", "demo", "--motions", str(real_motions), "--classifier",
                 str(classifier), "--checkpoint", str(odmo_checkpoint), "--repeats", "3",
                 "--json", str(out))
    result = json.loads(out.read_text())
    assert set(result["metrics"]) == set(METRICS) and not result["skipped"]
    for name, row in result["metrics"].items():
        assert isinstance(row["mean"], float) and row["ci"] >= 0 and len(row["values"]) == 3, name
        if name not in ("mode_homogeneity", "dist_e"):
            assert isinstance(row["real"]["mean"], float) and row["real"]["ci"] >= 0, name
    assert result["n_motions"] == 24 and result["repeats"] == 3
    assert result["protocol"]["name"] == "bootstrap"
    printed = capsys.readouterr().out
    assert "mmd_avg" in printed and "±" in printed and str(out) in printed
    assert result["mmd_protocol"]["name"] == "heldout" and "mmd_seq [heldout]" in printed


def test_paper_mmd_protocol_replaces_mmd_and_names_itself(real_motions, workdir, capsys):
    out = workdir / "paper.json"
    call_command("evaluate", "--dataset", "demo", "--motions", str(real_motions), "--metrics",
                 "mmd_avg,mmd_seq,apd", "--repeats", "2", "--mmd-protocol", "paper", "--json", str(out))
    result = json.loads(out.read_text())
    assert result["mmd_protocol"]["name"] == "paper"
    assert "training clips" in result["mmd_protocol"]["description"]
    for name in ("mmd_avg", "mmd_seq"):
        row = result["metrics"][name]
        assert row["mmd_protocol"] == "paper" and len(row["values"]) == 2
        assert isinstance(row["mean"], float) and isinstance(row["real"]["mean"], float)
    assert "mmd_protocol" not in result["metrics"]["apd"]
    assert list(result["metrics"]) == ["mmd_avg", "mmd_seq", "apd"]  # in the order asked
    printed = capsys.readouterr().out
    assert "MMD protocol paper:" in printed and "mmd_avg [paper]" in printed
    with pytest.raises(CommandError, match="--mmd-protocol paper measures one set"):
        call_command("evaluate", "--dataset", "demo", "--protocol", "a2m", "--checkpoint",
                     str(real_motions), "--mmd-protocol", "paper", "--json", str(out))


def test_training_mmd_scores_motions_against_the_training_clips_by_the_paper_protocol():
    from motion_metrics.evaluate import EvaluationError, training_mmd

    clips = get_dataset("demo").clips(frames=FRAMES, actions=["walk", "jump"])
    rng = np.random.default_rng(0)
    copies = [clips[i] for i in rng.choice(len(clips), 12, replace=False)]
    noisy = [clip.with_joints(clip.joints + rng.normal(0, 0.3, clip.joints.shape)) for clip in copies]
    near = training_mmd(copies, clips, seed=1)
    assert 0 <= near < training_mmd(noisy, clips, seed=1) and near == training_mmd(copies, clips, seed=1)
    assert training_mmd(copies, clips, "mmd_avg", repeats=2) >= 0
    with pytest.raises(EvaluationError, match="'fid' is not an MMD of the paper protocol"):
        training_mmd(copies, clips, "fid")
    with pytest.raises(EvaluationError, match="no training clips of run"):
        training_mmd([make_motion(frames=FRAMES, action="run")], clips)


def test_mode_homogeneity_groups_the_real_test_clips_by_the_models_modes(real_motions, odmo_checkpoint,
                                                                         workdir, capsys):
    """Seed 001, Sec. 4.3.1: the metric is of real clips; the generated motions do not enter it."""
    results = []
    for name, motions in (("a", real_motions), ("b", write_motions(
            workdir / "other.npz", sample_real(get_dataset("demo"), None, 3, frames=FRAMES, seed=7)))):
        out = workdir / f"modes_{name}.json"
        call_command("evaluate", "--dataset", "demo", "--motions", str(motions), "--checkpoint",
                     str(odmo_checkpoint), "--metrics", "mode_homogeneity", "--repeats", "2",
                     "--json", str(out), verbosity=0)
        results.append(json.loads(out.read_text())["metrics"]["mode_homogeneity"])
    assert results[0]["values"] == results[1]["values"] and results[0]["real"] is None
    assert np.isfinite(results[0]["mean"])
    out = workdir / "modes_none.json"
    call_command("evaluate", "--dataset", "demo", "--motions", str(real_motions), "--metrics",
                 "mode_homogeneity", "--repeats", "2", "--json", str(out))
    assert "mode of each real test clip" in json.loads(out.read_text())["skipped"]["mode_homogeneity"]
    assert "pass --checkpoint" in capsys.readouterr().out


def test_evaluate_rejects_a_checkpoint_without_modes(classifier, real_motions, workdir, tmp_path):
    cls = get_method("skeleton_vae")
    model = cls(cls.Config.preset("tiny"), "h36m17", ["walk"], 25.0, FRAMES)
    path = model.save(tmp_path / "vae.pt")
    with pytest.raises(CommandError, match="skeleton_vae model, which has no modes"):
        call_command("evaluate", "--dataset", "demo", "--motions", str(real_motions), "--checkpoint",
                     str(path), "--json", str(workdir / "x.json"))


def test_evaluate_by_a2ms_protocol_samples_fresh_motions_per_repeat(classifier, workdir, capsys):
    data = get_dataset("demo")
    cls = get_method("cond_gru")
    model = cls(cls.Config.preset("tiny"), data.skeleton, ["walk", "run"], 25.0, FRAMES)
    model.fit(data.clips(frames=FRAMES, max_per_take=1, actions=["walk", "run"]), 2, progress=False)
    checkpoint = model.save(workdir / "cond_gru.pt")
    out = workdir / "a2m.json"
    call_command("evaluate", "--dataset", "demo", "--protocol", "a2m", "--checkpoint", str(checkpoint),
                 "--n", "10", "--classifier", str(classifier), "--metrics", "fid,accuracy,apd",
                 "--repeats", "3", "--json", str(out))
    result = json.loads(out.read_text())
    assert result["protocol"]["name"] == "a2m" and result["n_motions"] == 10
    assert result["actions"] == {"run": 5, "walk": 5}
    assert result["protocol"]["real"] == "held-out clips against another draw of the held-out clips"
    fid = result["metrics"]["fid"]
    assert len(set(fid["values"])) == 3 and fid["real"]["mean"] is not None
    printed = capsys.readouterr().out
    assert "protocol a2m: Action2Motion's: a fresh set of motions per repeat" in printed
    with pytest.raises(CommandError, match="pass --checkpoint and no --motions"):
        call_command("evaluate", "--dataset", "demo", "--protocol", "a2m", "--json", str(out))
    with pytest.raises(CommandError, match=r"pass --motions F.npz \(or --protocol a2m"):
        call_command("evaluate", "--dataset", "demo", "--json", str(out))


def test_evaluate_without_classifier_skips_feature_metrics(real_motions, workdir, capsys):
    out = workdir / "no_classifier.json"
    call_command("evaluate", "--dataset", "demo", "--motions", str(real_motions),
                 "--metrics", "fid,mmd_seq,n_apd", "--repeats", "2", "--json", str(out))
    result = json.loads(out.read_text())
    assert set(result["metrics"]) == {"mmd_seq", "n_apd"}
    assert "classifier" in result["skipped"]["fid"]
    assert "skipped fid" in capsys.readouterr().out


def test_evaluate_rejects_motions_of_another_skeleton(classifier, workdir):
    path = write_motions(workdir / "other.npz", [make_motion(frames=FRAMES, skeleton="humanact12", seed=i)
                                                 for i in range(3)])
    with pytest.raises(CommandError, match="skeleton 'humanact12', but dataset 'demo' is 'h36m17'"):
        call_command("evaluate", "--dataset", "demo", "--motions", str(path), "--classifier",
                     str(classifier), "--json", str(workdir / "x.json"))


def test_evaluate_rejects_motions_of_another_length(classifier, workdir):
    motions = sample_real(get_dataset("demo"), "walk,run", 2, frames=30, seed=0)
    path = write_motions(workdir / "long.npz", motions)
    with pytest.raises(CommandError, match="30 frames, the classifier reads 20"):
        call_command("evaluate", "--dataset", "demo", "--motions", str(path), "--classifier",
                     str(classifier), "--json", str(workdir / "x.json"))


def test_evaluate_rejects_actions_the_classifier_does_not_know(workdir):
    narrow = workdir / "narrow.pt"
    call_command("train_classifier", "--dataset", "demo", "--actions", "walk,run", "--frames",
                 str(FRAMES), "--iters", "2", "--preset", "tiny", "--out", str(narrow), verbosity=0)
    motions = sample_real(get_dataset("demo"), "walk,jump", 2, frames=FRAMES, seed=0)
    path = write_motions(workdir / "jump.npz", motions)
    with pytest.raises(CommandError, match="classifier knows no action 'jump'"):
        call_command("evaluate", "--dataset", "demo", "--motions", str(path), "--classifier",
                     str(narrow), "--json", str(workdir / "x.json"))


def test_evaluate_and_train_classifier_report_bad_arguments(real_motions, workdir):
    with pytest.raises(CommandError, match="unknown metric 'fidd'"):
        call_command("evaluate", "--dataset", "demo", "--motions", str(real_motions),
                     "--metrics", "fidd", "--json", str(workdir / "x.json"))
    with pytest.raises(CommandError, match="does not exist"):
        call_command("evaluate", "--dataset", "demo", "--motions", str(workdir / "none.npz"),
                     "--json", str(workdir / "x.json"))
    with pytest.raises(CommandError, match="has no subjects"):
        call_command("train_classifier", "--dataset", "demo", "--test-subjects", "S1",
                     "--out", str(workdir / "x.pt"), verbosity=0)
