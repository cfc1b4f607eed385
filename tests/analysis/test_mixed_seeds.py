"""Training seeds in the mixed models: a checkpoint's random intercept (or worth) where a
source's clips come from several trainings, as the crossed bootstrap resamples them."""

import numpy as np
import pandas as pd
import pytest

from analysis import mixed, simulate
from analysis.registry import get_analysis
from analysis.study import analyse
from tests.analysis.conftest import config


def scores(rng, seeds=4, clips=4, people=30, seed_sd=1.0, clip_sd=0.2):
    """Scores of two sources trained with ``seeds`` seeds each, plus real clips (no seed)."""
    rows = []
    for source in ("a", "b", "real"):
        for seed in range(1 if source == "real" else seeds):
            seed_effect = 0.0 if source == "real" else rng.normal(0, seed_sd)
            for clip in range(clips):
                effect = seed_effect + rng.normal(0, clip_sd)
                for person in range(people):
                    rows.append({"source": source,
                                 "training_seed": np.nan if source == "real" else seed,
                                 "stimulus": f"{source}-{seed}-{clip}", "pcode": f"p{person}",
                                 "score": 3 + effect + rng.normal(0, 1)})
    return pd.DataFrame(rows)


def test_sources_with_several_seeds_and_their_checkpoints():
    rows = scores(np.random.default_rng(0), seeds=3, clips=2, people=10)
    assert mixed.seeded_sources(rows) == {"a": 3, "b": 3}
    labels = mixed.checkpoints_of(rows)
    assert labels[rows["source"] == "real"].isna().all()
    assert labels[rows["source"] == "a"].nunique() == 3
    checkpoints = mixed.clip_checkpoints(rows)
    assert checkpoints["a-2-1"] == checkpoints["a-2-0"] != checkpoints["a-1-0"]
    assert "real-0-0" not in checkpoints
    # One seed per source, or no column: no checkpoint term, clips as before.
    assert mixed.checkpoints_of(rows.assign(training_seed=0)) is None
    assert mixed.clip_checkpoints(rows.drop(columns="training_seed")) is None
    # Degrees of freedom count a several-seed source's seeds, not its clips.
    assert mixed.degrees_of_freedom(rows, "a", "b") == 4  # (3 - 1) + (3 - 1)
    assert mixed.degrees_of_freedom(rows, "a", "real") == 2 + 1  # seeds, then clips - 1
    assert mixed.degrees_of_freedom(rows.drop(columns="training_seed"), "a", "b") == 9  # min(P - 1, clips - 1 twice)


def test_linear_model_gives_the_seeds_a_variance_and_wider_intervals():
    rows = scores(np.random.default_rng(1))
    fitted = mixed.linear(rows, "score")
    components = fitted["components"].set_index("component")
    assert list(components.index) == ["participants", "clips", "training seeds", "residual"]
    assert components.loc["training seeds", "variance"] > components.loc["clips", "variance"]
    plain = mixed.linear(rows.drop(columns="training_seed"), "score")
    assert "training seeds" not in set(plain["components"]["component"])
    seeded = fitted["differences"].set_index(["a", "b"]).loc[("a", "b")]
    naive = plain["differences"].set_index(["a", "b"]).loc[("a", "b")]
    # The checkpoints' spread is sampling error of the method, not a fixed clip effect
    # known exactly: the seed-aware interval is the wider, on fewer degrees of freedom.
    assert seeded["df"] == 6 and naive["df"] == 29
    assert seeded["ci_high"] - seeded["ci_low"] > naive["ci_high"] - naive["ci_low"]


def test_logistic_model_has_the_seed_component():
    rng = np.random.default_rng(2)
    rows = scores(rng, seeds=3, clips=3, people=20)
    rows["real"] = (rows["score"] + rng.logistic(0, 1, len(rows)) > 3).astype(float)
    fitted = mixed.logistic(rows, "real", "real")
    assert "training seeds" in set(fitted["components"]["component"])
    assert set(fitted["differences"]["a"]) == {"a", "b"}
    assert (fitted["differences"]["df"] == 4).all()  # min(P - 1, seeds - 1 + clips - 1)


def test_worth_model_gives_each_checkpoint_a_random_worth():
    rng = np.random.default_rng(3)
    names = ["a", "b", "c"]
    seed_effect = {(s, k): rng.normal(0, 1.2) for s in names for k in range(4)}
    records = []
    for trial in range(1500):
        s1, s2 = rng.choice(names, 2, replace=False)
        k1, k2 = rng.integers(4, size=2)
        c1, c2 = f"{s1}-{k1}-{rng.integers(3)}", f"{s2}-{k2}-{rng.integers(3)}"
        p = 1 / (1 + np.exp(-(seed_effect[s1, k1] - seed_effect[s2, k2])))
        records.append({"first": s1, "second": s2, "first_clip": c1, "second_clip": c2,
                        "participant": f"p{trial % 50}", "trial": trial,
                        "won": float(rng.random() < p)})
    pairs = pd.DataFrame(records)
    checkpoints = {f"{s}-{k}-{c}": f"{s} / seed {k}" for s in names for k in range(4)
                   for c in range(3)}
    seeded = mixed.worth(pairs, names, checkpoints=checkpoints)
    plain = mixed.worth(pairs, names)
    components = seeded["components"].set_index("component")
    assert "training seeds" in components.index
    assert components.loc["training seeds", "variance"] > components.loc["clips", "variance"]
    assert (seeded["differences"]["sd"].to_numpy() > plain["differences"]["sd"].to_numpy()).all()


def test_a_worth_types_report_names_the_seed_term():
    study_type = next(name for name in simulate.simulated_types()
                      if get_analysis(name).mixed_model == "worth")
    table = simulate.simulate(study_type, {"a": 0.0, "b": 0.5, "c": 1.0}, participants=20,
                              trials=8, clips_per_source=6, clip_sd=0.3, seed=4)
    clip_number = table["stimulus"].astype("category").cat.codes
    table["training_seed"] = np.where(table["source"] == "c", np.nan, clip_number % 3)
    result = analyse(table, config(mixed_models=True, bootstrap=50))
    components = {t.name: t.frame for t in result.analysis.tables}["variance_components"]
    assert "training seeds" in set(components["component"])
    text = result.methods()
    assert mixed.SEED_METHOD[1:] in text and "counted its seeds" not in text  # normal quantiles


def test_clips_without_a_seed_of_a_several_seed_source_are_a_checkpoint_of_their_own():
    rows = scores(np.random.default_rng(5), seeds=3, clips=2, people=10)
    unknown = rows["stimulus"].str.startswith("a-2-")
    rows.loc[unknown, "training_seed"] = np.nan
    rows.index = rows.index * 3 + 7  # not a range index
    assert mixed.seeded_sources(rows) == {"a": 3, "b": 3}  # seeds 0, 1 and "unknown"
    labels = mixed.checkpoints_of(rows)
    assert set(labels[unknown.to_numpy()]) == {"a / seed unknown"}
    assert labels[rows["source"] == "real"].isna().all()
    assert mixed.degrees_of_freedom(rows, "a", "b") == 4


def test_the_seed_term_benchmark_runs(monkeypatch, capsys):
    from benchmarks import bench_seed_term

    monkeypatch.setattr("sys.argv", ["bench_seed_term", "--studies", "1", "--participants", "6",
                                     "--seeds", "2", "--clips", "2"])
    bench_seed_term.main()
    assert "1 studies: covered with the seed term" in capsys.readouterr().out
