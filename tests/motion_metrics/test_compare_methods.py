"""compare_methods at a tiny scale; modes and end targets from ODMO through the .npz to evaluate."""

import json

import numpy as np
import pytest
import torch
from django.core.management import CommandError, call_command

from motion.datasets import get_dataset
from motion.formats import npz
from generation.methods import get_method
from motion_metrics import comparison as bench
from motion_metrics.comparison import Recipe, recipe_for, train_within_budget
from motion_metrics.comparison_report import _metric_table, _training_table
from motion_metrics.paper_numbers import A2M_TABLE_1, SA_GCN_TABLE_2
from tests.conftest import make_motion

torch.set_num_threads(1)

TINY = ["--iters", "3", "--repeats", "2", "--n", "3", "--classifier-iters", "5",
        "--classifier-preset", "tiny"]


def benchmark(tmp_path, *args, iters=3):
    out = tmp_path / "RESULTS.md"
    call_command("compare_methods", *args, *TINY, "--iters", str(iters),
                 "--work", str(tmp_path / "work"), "--out", str(out), verbosity=0)
    return out.read_text()


def record(tmp_path, stem, dataset="demo"):
    return json.loads((tmp_path / "work" / dataset / f"{stem}.json").read_text())


def test_paper_numbers_are_the_tables():
    assert A2M_TABLE_1.row("a2m").values["fid"] == 2.458 and A2M_TABLE_1.real.values["accuracy"] == 0.997
    for row in SA_GCN_TABLE_2.rows:  # averages of the unrounded per-class values
        classes = [value for key, value in row.values.items() if key != "accuracy"]
        assert len(classes) == 10 and abs(np.mean(classes) - row.values["accuracy"]) < 0.006


def test_command_trains_three_seeds_for_equal_iterations_and_reuses_its_work(tmp_path):
    text = benchmark(tmp_path, "--dataset", "demo", "--methods", "cond_gru,a2m_xyz",
                     "--presets", "cond_gru=tiny,a2m_xyz=tiny")
    assert "python manage.py compare_methods --dataset demo --iters 3 --seeds 0,1,2" in text
    assert "--classifier-preset tiny --mmd-protocol heldout --select last --out" in text
    assert text.count("Checkpoints: the last of each training (`--select last`).") == 2  # and the table
    assert "no GPU" in text and "Where we stand against the papers" in text
    assert "The main reason is training" not in text  # a cause is stated only where measured
    assert "3 training iterations per method, setting and training seed" in text
    assert "95 % t interval over seeds" in text and "Protocol: `bootstrap`" in text
    header = next(line for line in text.splitlines() if line.startswith("| method | FID"))
    assert header.split(" | ")[1:4] == ["FID ↓ (± seeds, t)", "± samples", "A2M (HumanAct12)"]
    assert "| **Real** (held-out vs training clips) |" in text and "0.092 ± 0.007" in text
    assert "Classifier confusion on the held-out clips" in text and "the state of iteration 5 is kept" in text
    row = next(line for line in text.splitlines() if line.startswith("| `cond_gru` |") and "±" in line)
    assert "40.61 ± 0.144" in row and len(row.split("|")) == 15  # 4 metrics: ours, ± samples, A2M's
    assert "| `cond_gru` | tiny | none |" in text and "| 3 × 3 |" in text  # preset, departures, it. × seeds
    results = json.loads((tmp_path / "work" / "results.json").read_text())
    entry = results["settings"][0]["methods"]["cond_gru"]
    assert [run["seed"] for run in entry["runs"]] == [0, 1, 2] and entry["iterations"] == [3, 3, 3]
    fid = entry["metrics"]["fid"]
    means = [run["mean"] for run in fid["seeds"]]
    assert len(set(means)) == 3 and np.isclose(fid["mean"], np.mean(means))  # three models
    assert np.isclose(fid["ci_seeds"], 4.302653 * np.std(means, ddof=1) / np.sqrt(3), rtol=1e-5)
    assert np.isclose(fid["ci_samples"], np.mean([run["ci"] for run in fid["seeds"]]))
    assert f"{fid['mean']:.3f} ± {fid['ci_seeds']:.3f}" in row and f"± {fid['ci_samples']:.3f}" in row
    for seed in (0, 1, 2):
        record = json.loads((tmp_path / "work" / "demo" / f"cond_gru-seed{seed}-it3.json").read_text())
        assert record["finished"] and record["iterations"] == 3 and record["signature"]["seed"] == seed
    checkpoint = tmp_path / "work" / "demo" / "cond_gru-seed2-it3.pt"
    written = checkpoint.stat().st_mtime_ns
    again = benchmark(tmp_path, "--dataset", "demo", "--methods", "cond_gru,a2m_xyz",
                      "--presets", "cond_gru=tiny,a2m_xyz=tiny")
    assert "6 of the 6 trainings were reused" in again
    assert checkpoint.stat().st_mtime_ns == written  # the same budget and seed reuse the checkpoint


def test_cond_gru_ranking_first_is_marked_as_starting_from_real_poses():
    from motion_metrics.comparison_report import _metric_table

    def entry(fid):
        return {"metrics": {"fid": {"mean": fid, "ci_seeds": 0.1, "ci_samples": 0.05}}}

    setting = {"tables": [], "protocol": "bootstrap", "real": {"fid": {"mean": 1.0, "ci": 0.02}},
               "methods": {"cond_gru": entry(2.0), "a2m": entry(3.0)}}
    text = "\n".join(_metric_table(setting, ["fid"], []))
    assert "| `cond_gru` | 2.000 ± 0.100 † | ± 0.050 |" in text and "first pose of a real training clip" in text
    assert "| **Real** (held-out vs training clips) | 1.000 | ± 0.020 |" in text
    setting["methods"]["a2m"] = entry(1.5)
    assert "†" not in "\n".join(_metric_table(setting, ["fid"], []))


def test_command_rejects_a_single_seed_and_both_budgets(tmp_path):
    with pytest.raises(CommandError, match="--seeds '0'.*at least 2"):
        benchmark(tmp_path, "--dataset", "demo", "--methods", "cond_gru", "--seeds", "0")
    with pytest.raises(CommandError, match="not allowed with argument"):
        call_command("compare_methods", "--dataset", "demo", "--iters", "3", "--budget", "1",
                     "--out", str(tmp_path / "r.md"), verbosity=0)


def test_command_on_h36m2d_compares_with_seeds_003_and_004(tmp_path, h36m_root):
    """The papers' way on real data: MMD by the paper protocol, the checkpoint of best MMD_seq."""
    text = benchmark(tmp_path, "--dataset", "h36m2d", "--data-root", str(h36m_root),
                     "--methods", "skeleton_vae,sa_gcn", "--presets", "skeleton_vae=tiny,sa_gcn=tiny",
                     "--subjects", "S1", "--mmd-protocol", "paper", "--select", "best-mmd-seq",
                     "--select-every", "1", "--select-n", "3")
    assert "S11" in text and "held-out subjects S9" in text
    assert "Settings run: h36m2d. **Not run**" in text
    assert "compare_methods --dataset h36m --iters 3 --seeds 0,1,2" in text
    assert (f"--mmd-protocol paper --select best-mmd-seq --select-every 1 --select-n 3 --out "
            f"{tmp_path / 'RESULTS_h36m.md'}" in text)  # the command for the setting not run keeps them
    header = next(line for line in text.splitlines() if line.startswith("| method | MMD_avg"))
    assert header.split(" | ")[1:] == ["MMD_avg ↓ (± seeds, t)", "± samples", "004 T1", "003 T1",
                                       "MMD_seq ↓ (± seeds, t)", "± samples", "004 T1", "003 T1",
                                       "accuracy ↑ (± seeds, t)", "± samples", "004 T2 |"]
    sa_gcn = next(line for line in text.splitlines() if line.startswith("| `sa_gcn` |") and "0.146" in line)
    assert "0.134" in sa_gcn and "0.593" in sa_gcn and sa_gcn.count("±") == 6
    assert "| SA-GCN (004 T2) | 0.42 |" in text and "FID ↓" in text
    mmd_line = next(line for line in text.splitlines() if line.startswith("Protocol:") and "MMD" in line)
    assert "MMD protocol: `paper` (per action, equal numbers of generated motions and training" in mmd_line
    assert "lowest MMD_seq (`paper` MMD protocol, against the training clips) of candidates every 1" in mmd_line
    assert ("| method | preset | departures from the paper | parameters | iterations | evaluated "
            "(lowest MMD_seq) |") in text
    results = json.loads((tmp_path / "work" / "results.json").read_text())
    assert results["mmd_protocol"] == "paper" and results["selection"]["every"] == 1
    entry = results["settings"][0]["methods"]["sa_gcn"]
    for run, chosen in zip(entry["runs"], entry["chosen"]):
        scores = {int(it): value for it, value in run["scores"].items()}
        assert set(scores) == {1, 2, 3} and chosen == min(scores, key=scores.get)
        saved = record(tmp_path, f"sa_gcn-seed{run['seed']}-it3-best-mmd-seq-every1-n3", "h36m2d")
        assert saved["evaluation"]["signature"]["iteration"] == chosen
        assert saved["evaluation"]["signature"]["mmd_protocol"] == "paper"
    row = next(line for line in text.splitlines() if line.startswith("| `sa_gcn` | tiny |"))
    assert " / ".join(map(str, entry["chosen"])) + " |" in row


def test_best_mmd_seq_evaluates_the_lowest_scoring_candidate_and_reruns_reuse_it(tmp_path, monkeypatch):
    best = {0: 2, 1: 3}  # the iteration whose checkpoint scores lowest, per seed
    calls = []

    def score(model, train, n, seed):
        calls.append((seed, model.iteration))
        return abs(model.iteration - best[seed]) + 0.5

    monkeypatch.setattr(bench, "candidate_score", score)
    args = ("--dataset", "demo", "--methods", "cond_gru", "--presets", "cond_gru=tiny", "--seeds", "0,1")
    picked = (*args, "--select", "best-mmd-seq", "--select-every", "1")
    text = benchmark(tmp_path, *picked)
    assert sorted(calls) == [(0, 1), (0, 2), (0, 3), (1, 1), (1, 2), (1, 3)]
    assert "--select best-mmd-seq --select-every 1 --select-n 50 --out" in text
    assert "| `cond_gru` | tiny | none | 5,091 | 3 × 2 | 2 / 3 |" in text
    folder = tmp_path / "work" / "demo"
    for seed in (0, 1):
        stem = f"cond_gru-seed{seed}-it3-best-mmd-seq-every1-n50"
        saved = record(tmp_path, stem)
        assert saved["iterations"] == 3 and saved["selection"]["chosen"] == best[seed]
        assert saved["evaluation"]["signature"]["iteration"] == best[seed]  # the chosen one is evaluated
        with np.load(folder / f"{stem}.npz") as data:
            assert len(data["joints"]) == 3 * 8
        # Only the best candidate stays beside the last checkpoint (for a longer run to compare with).
        assert [p.name for p in (folder / f"{stem}.candidates").iterdir()] == [f"it{best[seed]}.pt"]
    kept = folder / "cond_gru-seed0-it3-best-mmd-seq-every1-n50.candidates" / "it2.pt"
    written = kept.stat().st_mtime_ns
    calls.clear()
    again = benchmark(tmp_path, *picked)
    assert calls == [] and "2 of the 2 trainings were reused" in again and "| 3 × 2 | 2 / 3 |" in again
    assert kept.stat().st_mtime_ns == written
    last = benchmark(tmp_path, *args)  # another selection: its own runs, not the best ones
    assert "trainings were reused" not in last and "evaluated (lowest MMD_seq)" not in last
    assert record(tmp_path, "cond_gru-seed0-it3")["evaluation"]["signature"]["iteration"] == 3
    assert calls == [] and "| 3 × 2 | 2 / 3 |" in benchmark(tmp_path, *picked)
    longer = benchmark(tmp_path, *picked, iters=4)  # resumes; scores only the new candidate
    assert sorted(calls) == [(0, 4), (1, 4)] and "| 4 × 2 | 2 / 3 |" in longer
    assert record(tmp_path, "cond_gru-seed0-it3-best-mmd-seq-every1-n50")["iterations"] == 3  # kept


def test_best_mmd_seq_scores_real_candidates_of_odmo(tmp_path):
    """ODMO's candidates are finished (modes fitted) before they are scored and evaluated."""
    text = benchmark(tmp_path, "--dataset", "demo", "--methods", "odmo", "--presets", "odmo=tiny",
                     "--seeds", "0,1", "--select", "best-mmd-seq", "--select-every", "2",
                     "--select-n", "4", iters=4)
    results = json.loads((tmp_path / "work" / "results.json").read_text())
    entry = results["settings"][0]["methods"]["odmo"]
    assert not entry.get("errors") and entry["metrics"]["fid"]["mean"] is not None
    for run in entry["runs"]:
        scores = {int(it): value for it, value in run["scores"].items()}
        assert set(scores) == {2, 4} and all(np.isfinite(list(scores.values())))
        assert run["chosen"] == min(scores, key=scores.get) and run["select_seconds"] > 0
    assert f"| 4 × 2 | {entry['chosen'][0]} / {entry['chosen'][1]} |" in text
    assert "checkpoint selection" in text and "(modes)" in text


@pytest.mark.parametrize("args, message", [
    (("--select", "best"), r"--select: invalid choice: 'best' \(choose from 'last', 'best-mmd-seq'\)"),
    (("--mmd-protocol", "ours"), r"--mmd-protocol: invalid choice: 'ours' \(choose from 'authors', 'heldout', 'paper'\)"),
    (("--select", "best-mmd-seq", "--select-every", "0"), r"--select-every must be from 1 to --iters \(3\); got 0"),
    (("--select", "best-mmd-seq", "--select-every", "4"), r"--select-every must be from 1 to --iters \(3\); got 4"),
    (("--select", "best-mmd-seq", "--select-n", "1"), "--select-n must be at least 2"),
    (("--select-every", "2",), "--select-every and --select-n go with --select best-mmd-seq, not --select last"),
])
def test_command_rejects_bad_selections_naming_the_option(tmp_path, args, message):
    with pytest.raises(CommandError, match=message):
        benchmark(tmp_path, "--dataset", "demo", "--methods", "cond_gru", *args)


def test_best_mmd_seq_with_a_time_budget_needs_its_interval(tmp_path):
    with pytest.raises(CommandError, match="--select best-mmd-seq with --budget needs --select-every N"):
        call_command("compare_methods", "--dataset", "demo", "--budget", "1", "--select", "best-mmd-seq",
                     "--out", str(tmp_path / "r.md"), verbosity=0)


def test_tables_name_their_mmd_protocol_and_checkpoint_selection():
    entry = {"recipe": "tiny", "parameters": 10, "runs": [
        {"seed": seed, "iterations": 6, "chosen": chosen, "seconds": 1.0, "cpu_seconds": 1.0}
        for seed, chosen in ((0, 2), (1, 6))],
        "metrics": {"mmd_seq": {"mean": 0.5, "ci_seeds": 0.1, "ci_samples": 0.01}}}
    setting = {"tables": [], "protocol": "bootstrap", "real": {}, "methods": {"a2m": entry},
               "mmd_protocol": "heldout", "selection": {"rule": "last"}}
    line = _metric_table(setting, ["mmd_seq"], [])[0]
    assert "MMD protocol: `heldout` (distinct drawn motions against every held-out clip" in line
    assert line.endswith("Checkpoints: the last of each training (`--select last`).")
    assert "evaluated" not in "\n".join(_training_table(setting))
    setting.update(mmd_protocol="paper", selection={"rule": "best-mmd-seq", "every": 2, "n": 50, "repeats": 3})
    line = _metric_table(setting, ["mmd_seq"], [])[0]
    assert "MMD protocol: `paper` (per action, equal numbers" in line and "candidates every 2 iterations" in line
    assert "| `a2m` | tiny | none | 10 | 6 × 2 | 2 / 6 | 1 / 1 | 1 / 1 |  |" in _training_table(setting)
    setting["methods"]["a2m"]["metrics"] = {"fid": {"mean": 1.0, "ci_seeds": 0.1, "ci_samples": 0.01}}
    line = _metric_table(setting, ["fid"], [])[0]  # no MMD column: only the selection is named
    assert "MMD protocol: " not in line and "lowest MMD_seq (`paper` MMD protocol" in line


def test_training_stops_at_equal_iterations_and_resumes_to_more(tmp_path):
    clips = get_dataset("demo").clips(frames=12, max_per_take=1, actions=["walk", "run"])
    recipe = Recipe("tiny")
    model, first = train_within_budget("cond_gru", clips, ["walk", "run"], None, tmp_path, recipe,
                                       seed=1, iters=4)
    assert model.iteration == first["iterations"] == 4 and (tmp_path / "cond_gru-seed1.pt").is_file()
    model, again = train_within_budget("cond_gru", clips, ["walk", "run"], None, tmp_path, recipe,
                                       seed=1, iters=4)
    assert again["reused"] and model.iteration == 4
    model, more = train_within_budget("cond_gru", clips, ["walk", "run"], None, tmp_path, recipe,
                                      seed=1, iters=7)
    assert model.iteration == more["iterations"] == 7 and not more["reused"]
    model, fewer = train_within_budget("cond_gru", clips, ["walk", "run"], None, tmp_path, recipe,
                                       seed=1, iters=4)
    assert model.iteration == fewer["iterations"] == 4  # past the target: trained afresh


def test_iteration_budget_shortens_first_phases_of_default_recipes():
    assert recipe_for("skeleton_gan", None, 80).describe() == "demo (pretrain_iters=40)"
    assert recipe_for("two_stage_gan", None, 80).changes == {"pose_iterations": 40}
    assert recipe_for("odmo", None, 100).changes == {"teacher_forcing_iters": 75}
    assert recipe_for("odmo", None, 2000).changes == {}  # the demo preset's 1,000 fit in 75 %
    assert recipe_for("skeleton_gan", None, None).changes == {}
    # A preset named for the method takes the same schedule.
    assert recipe_for("skeleton_gan", {"skeleton_gan": "paper"}, 80).changes == {"pretrain_iters": 40}
    assert recipe_for("a2m", None, 80) == Recipe()


def test_full_schedule_refuses_a_budget_inside_the_first_phase():
    """The study builds' and ``train``'s other rule: the preset's phases as they are, and a
    budget that ends inside the first is refused, naming the phase and the fix."""
    from generation.methods.schedule import ScheduleError, recipe_for as schedule

    with pytest.raises(ScheduleError, match=r"c_skeleton_gan pretrains its frame decoder for its "
                                            r"first 10,000 iterations \(pretrain_iters of the paper "
                                            r"preset\); 2,000 iterations end inside that phase"):
        schedule("c_skeleton_gan", "paper", 2000, "full")
    assert schedule("c_skeleton_gan", "paper", 12_000, "full").changes == {}
    assert schedule("a2m", "paper", 10, "full") == Recipe("paper")
    with pytest.raises(ScheduleError, match="unknown schedule 'fast'"):
        schedule("a2m", "paper", 10, "fast")
    # Under the benchmark schedule the first stage is shortened, but never to the whole budget.
    with pytest.raises(ScheduleError, match=r"two_stage_gan trains its pose GAN before the motion "
                                            r"generator \(pose_iterations\) and needs at least 2"):
        schedule("two_stage_gan", "tiny", 1, "benchmark")
    assert schedule("two_stage_gan", "paper", 2, "benchmark").changes == {"pose_iterations": 1}


def test_training_resumes_to_a_larger_budget(tmp_path):
    clips = get_dataset("demo").clips(frames=12, max_per_take=1, actions=["walk", "run"])
    recipe = Recipe("tiny")
    model, first = train_within_budget("cond_gru", clips, ["walk", "run"], 0.3, tmp_path, recipe)
    done = first["iterations"]
    assert model.iteration == done > 0 and first["seconds"] >= 0.3
    model, second = train_within_budget("cond_gru", clips, ["walk", "run"], 0.6, tmp_path, recipe)
    assert model.iteration == second["iterations"] > done and second["seconds"] >= 0.6


def test_training_restarts_when_the_config_or_version_changed(tmp_path):
    """A record of another version or config (e.g. a changed default) is not resumed."""
    clips = get_dataset("demo").clips(frames=12, max_per_take=1, actions=["walk", "run"])
    recipe = Recipe("tiny")
    model, first = train_within_budget("cond_gru", clips, ["walk", "run"], 0.2, tmp_path, recipe)
    record_path = tmp_path / "cond_gru-seed0.json"
    record = json.loads(record_path.read_text())
    assert record["signature"]["version"] == 1 and "config" in record["signature"]
    for stale in ({"version": 0}, {"config": {**record["signature"]["config"], "hidden": 1}}):
        record_path.write_text(json.dumps({**record, "signature": {**record["signature"], **stale}}))
        _, again = train_within_budget("cond_gru", clips, ["walk", "run"], 0.2, tmp_path, recipe)
        assert not again["reused"] and again["signature"] == record["signature"]


def test_npz_round_trips_modes_and_end_targets(tmp_path):
    motions = [make_motion(frames=6, seed=i) for i in range(3)]
    for i, motion in enumerate(motions):
        motion.meta.update(mode=i % 2, end=np.array([0.1 * i, 0.2, 0.0]))
    path = npz.save(tmp_path / "m.npz", motions)
    with np.load(path) as data:
        assert data["modes"].tolist() == [0, 1, 0] and data["end_targets"].shape == (3, 3)
    loaded = npz.load(path)
    assert [m.meta["mode"] for m in loaded] == [0, 1, 0]
    assert np.allclose(np.stack([m.meta["end"] for m in loaded]), [[0, 0.2, 0], [0.1, 0.2, 0], [0.2, 0.2, 0]])
    del motions[1].meta["mode"]
    with np.load(npz.save(tmp_path / "n.npz", motions)) as data:
        assert "modes" not in data.files and "end_targets" in data.files


def test_evaluate_measures_modes_and_end_targets_of_an_odmo_file(tmp_path):
    actions, frames = ["walk", "wave"], 12
    cls = get_method("odmo")
    model = cls(cls.Config.preset("tiny"), "h36m17", actions, 25.0, frames)
    model.fit(get_dataset("demo").clips(frames=frames, max_per_take=2, actions=actions), 20,
              progress=False)
    checkpoint = model.save(tmp_path / "odmo.pt")
    motions_path, result_path = tmp_path / "odmo.npz", tmp_path / "result.json"
    call_command("sample", "odmo", "--checkpoint", str(checkpoint), "--action", "walk,wave",
                 "--n", "4", "--end", "0.5,0.2", "--out", str(motions_path), verbosity=0)
    with np.load(motions_path) as data:
        modes, targets = data["modes"], data["end_targets"]
    assert modes.shape == (8,) and targets.shape == (8, 3) and np.allclose(targets[:, :2], [0.5, 0.2])
    call_command("evaluate", "--dataset", "demo", "--motions", str(motions_path), "--checkpoint",
                 str(checkpoint), "--metrics", "mode_homogeneity,dist_e", "--repeats", "2",
                 "--json", str(result_path), verbosity=0)
    result = json.loads(result_path.read_text())
    assert not result["skipped"]
    assert result["metrics"]["dist_e"]["mean"] >= 0
    assert np.isfinite(result["metrics"]["mode_homogeneity"]["mean"])
    chosen = tmp_path / "mode.npz"
    call_command("sample", "odmo", "--checkpoint", str(checkpoint), "--action", "walk", "--n", "3",
                 "--mode", "0", "--out", str(chosen), verbosity=0)
    with np.load(chosen) as data:
        assert data["modes"].tolist() == [0, 0, 0] and "end_targets" not in data.files


def test_a_budget_sweep_resumes_methods_without_phases_and_reports_every_budget(tmp_path):
    """``--iters 2,4``: cond_gru trains once (the 4-iteration run resumes the 2-iteration
    one, both checkpoints kept); skeleton_gan, whose pretraining takes half the budget,
    trains afresh per budget; the report is the main budget's with a table per metric."""
    out = tmp_path / "RESULTS.md"
    call_command("compare_methods", "--dataset", "demo", "--methods", "cond_gru,skeleton_gan",
                 "--presets", "cond_gru=tiny,skeleton_gan=tiny", "--repeats", "2", "--n", "3",
                 "--classifier-iters", "5", "--classifier-preset", "tiny", "--iters", "2,4",
                 "--main-iters", "2", "--seeds", "0,1", "--work", str(tmp_path / "work"),
                 "--out", str(out), verbosity=0)
    text = out.read_text()
    assert "--iters 2,4 --main-iters 2" in text
    assert "2 training iterations per method, setting and training seed" in text
    assert "## Training budget: the same methods and seeds at 2, 4 iterations" in text
    fid = text[text.index("FID ↓ (classifier: `tiny` preset, held-out accuracy"):]
    row = next(line for line in fid.splitlines() if line.startswith("| `cond_gru` |"))
    assert row.count("±") == 2 and row.rstrip(" |").split("| ")[-1] in (
        "intervals overlap", "better", "worse")
    for seed in (0, 1):
        assert record(tmp_path, f"cond_gru-seed{seed}-it2")["iterations"] == 2
        assert record(tmp_path, f"cond_gru-seed{seed}-it4")["iterations"] == 4
        # tiny pretrains for 2: half of 2 iterations is 1, half of 4 is the preset's own 2.
        assert record(tmp_path, f"skeleton_gan-seed{seed}-it2")["signature"]["changes"] == {
            "pretrain_iters": 1}
        assert record(tmp_path, f"skeleton_gan-seed{seed}-it4")["signature"]["changes"] == {}
    sweep = json.loads((tmp_path / "work" / "sweep.json").read_text())
    assert sweep["iters"] == [2, 4] and sweep["main"] == 2 and len(sweep["results"]) == 2
    with pytest.raises(CommandError, match="--main-iters 3 is not one of --iters 2,4"):
        call_command("compare_methods", "--dataset", "demo", "--iters", "2,4", "--main-iters", "3",
                     "--out", str(out), verbosity=0)


def test_rankings_only_where_intervals_separate_and_both_real_definitions_are_named():
    from motion_metrics.comparison_report import _setting_facts

    def entry(accuracy, ci, fid):
        return {"metrics": {"accuracy": {"mean": accuracy, "ci_seeds": ci},
                            "fid": {"mean": fid, "ci_seeds": 0.1}}}

    setting = {"dataset": "h36m", "tables": ["000_table_1"], "classifier": {"test_accuracy": 0.5},
               "real": {"fid": {"mean": 2.0}}, "real_a2m": {"fid": {"mean": 0.5}},
               "methods": {"a2m": entry(0.40, 0.05, 6.0), "cond_gru": entry(0.36, 0.05, 7.0)}}
    text = " ".join(_setting_facts(setting))
    assert "no method is first" in text and "most recognisable" not in text
    assert "3.0× the FID of held-out against training clips (2, our Real row)" in text
    assert "12× that of two draws of the held-out clips (0.5, the definition of Action2Motion's" in text
    setting["methods"]["a2m"] = entry(0.60, 0.05, 6.0)
    assert "most recognisable samples on h36m are `a2m`'s" in " ".join(_setting_facts(setting))


def test_the_old_command_name_runs_compare_methods():
    """``benchmark_methods`` (the former name) is ``compare_methods`` with a note."""
    from django.core.management import load_command_class

    old = load_command_class("studyapp.offline", "benchmark_methods")
    new = load_command_class("studyapp.offline", "compare_methods")
    assert isinstance(old, type(new)) and old.help.startswith("Renamed: run `compare_methods`")


def test_a_setting_run_into_a_file_beside_is_named_not_asked_for(tmp_path):
    from motion_metrics.comparison_report import _not_run, runs_beside

    same = "python manage.py compare_methods --dataset h36m --iters 3 --out docs/RESULTS_h36m.md"
    other = "python manage.py compare_methods --dataset=h36m,h36m2d --iters 5 --out=docs/RESULTS_a.md"
    (tmp_path / "RESULTS_h36m.md").write_text(f"# Results\n\nWritten by\n\n```\n{same}\n```\n")
    (tmp_path / "RESULTS_a.md").write_text(f"```\n{other}\n```\n")  # first by name, other options
    (tmp_path / "NOTES.md").write_text("```\nmake test\n```\n")
    (tmp_path / "QUOTE.md").write_text("```\ncompare_methods --dataset h36m don't\n```\n")  # unreadable
    (tmp_path / "folder.md").mkdir()
    out = tmp_path / "RESULTS.md"
    out.write_text("```\npython manage.py compare_methods --dataset h36m2d\n```\n")  # itself
    beside = runs_beside(out)
    assert beside == {"h36m": [("RESULTS_a.md", other), ("RESULTS_h36m.md", same)],
                      "h36m2d": [("RESULTS_a.md", other)]}
    result = {"settings": [{"dataset": "h36m2d"}]}
    command = "python manage.py compare_methods --dataset h36m2d --iters 3 --out docs/RESULTS.md"
    named = _not_run(result, command, beside)  # the file with the same options wins
    assert named == ["- Settings run: h36m2d. Run with the same options by its own command (at "
                     "the top of its file): h36m in `RESULTS_h36m.md` beside this file.", ""]
    # At other settings the files are named, and the command with this run's options
    # writes beside this file under a name no other run holds.
    elsewhere = "\n".join(_not_run(result, command.replace("--iters 3", "--iters=7"), beside))
    assert "Run at other settings" in elsewhere and "`RESULTS_a.md`, `RESULTS_h36m.md`" in elsewhere
    assert "**Not run** with these options" in elsewhere
    assert "--dataset h36m --iters=7 --out docs/RESULTS_h36m_2.md" in elsewhere
    asked = "\n".join(_not_run(result, command.replace("--out docs/RESULTS.md", "--out=docs/RESULTS.md"), {}))
    assert "**Not run** at this budget" in asked and "--dataset h36m --iters 3 --out docs/RESULTS_h36m.md" in asked
