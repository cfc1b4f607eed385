"""The Bradley-Terry logistic mixed model of the worth types, beside the crossed bootstrap.

The types are those whose plug-in says a worth model fits its answers
(``StudyAnalysis.mixed_model == "worth"``), asked of the registry.
"""

import numpy as np
import pandas as pd
import pytest

from analysis import mixed, simulate
from analysis.registry import get_analysis
from analysis.study import analyse
from tests.analysis.conftest import config

STRENGTHS = {"a": 0.0, "b": 0.6, "c": 1.2}
TRUE = {name: value - np.mean(list(STRENGTHS.values())) for name, value in STRENGTHS.items()}
WORTH_TYPES = [name for name in simulate.simulated_types()
               if get_analysis(name).mixed_model == "worth"]


def test_the_worth_types_fit_the_worth_model():
    assert len(WORTH_TYPES) >= 4


@pytest.mark.parametrize("study_type", WORTH_TYPES)
def test_recovers_known_worths_and_agrees_with_the_bootstrap(study_type):
    table = simulate.simulate(study_type, STRENGTHS, participants=40, trials=12,
                              actions=("x", "y"), clips_per_source=5, clip_sd=0.4,
                              clips_per_trial=3, seed=3)
    result = analyse(table, config(mixed_models=True, bootstrap=100))
    tables = {t.name: t.frame for t in result.analysis.tables}
    worth = tables["mixed_model_worth"].set_index("source")
    # Where the type's headline is a Bradley-Terry or Plackett-Luce worth, the simulated
    # raters prefer by it (logistic or Gumbel noise of scale 1 on the strengths): the
    # log-worths are the centred strengths. (Graded raters cut a logistic latent at +-0.5
    # for "no preference": given a direction that is not exactly Bradley-Terry, and the
    # check is against the bootstrap's Davidson worths only.)
    exact = any(name in result.analysis.measure for name in ("Bradley-Terry", "Plackett-Luce"))
    for name, value in TRUE.items():
        if exact:
            assert worth.loc[name, "estimate"] == pytest.approx(value, abs=0.3)
            assert worth.loc[name, "ci_low"] < value < worth.loc[name, "ci_high"]
        assert worth.loc[name, "estimate"] == pytest.approx(worth.loc[name, "bootstrap"], abs=0.15)
    assert list(worth["estimate"].sort_values().index) == ["a", "b", "c"]
    model = tables["mixed_model"].set_index(["a", "b"])
    assert model.loc[("a", "c"), "p_holm"] < 0.05
    if exact:
        ours = tables["differences"].set_index(["a", "b"])
        # Both measure each difference's uncertainty over participants and clips.
        ratio = model["sd"] / ours.loc[model.index, "se"]
        assert ratio.between(0.5, 2.0).all(), ratio
    components = tables["variance_components"].set_index("component")
    assert components["share"].sum() == pytest.approx(1.0)
    assert "BinomialBayesMixedGLM" in result.methods()


def test_worth_recovers_known_worths_and_components_of_bradley_terry_pairs():
    rng = np.random.default_rng(1)
    names = ["a", "b", "c", "d"]
    theta = np.array([-0.9, -0.3, 0.3, 0.9])
    n_clips, n_people, n = 40, 60, 6000
    clip_source = np.arange(n_clips) % 4
    clip_effect = rng.normal(0, 0.5, n_clips)
    person_effect = rng.normal(0, 0.4, (n_people, 4))
    first, second = rng.integers(0, n_clips, n), rng.integers(0, n_clips, n)
    person = rng.integers(0, n_people, n)
    s1, s2 = clip_source[first], clip_source[second]
    eta = (theta[s1] - theta[s2] + clip_effect[first] - clip_effect[second]
           + person_effect[person, s1] - person_effect[person, s2] + 0.2)
    pairs = pd.DataFrame({"first": np.array(names)[s1], "second": np.array(names)[s2],
                          "first_clip": first, "second_clip": second, "participant": person,
                          "trial": np.arange(n),
                          "won": (rng.random(n) < 1 / (1 + np.exp(-eta))).astype(float)})
    fitted = mixed.worth(pairs, names, sided=True)
    scores = fitted["scores"].set_index("source")
    assert scores["estimate"].to_numpy() == pytest.approx(theta, abs=0.25)
    assert ((scores["ci_low"] < theta) & (theta < scores["ci_high"])).all()
    assert fitted["position"]["estimate"] == pytest.approx(0.2, abs=0.1)
    sd = fitted["components"].set_index("component")["sd"]
    assert sd["clips"] == pytest.approx(0.5, rel=0.4)
    assert sd["participants"] == pytest.approx(0.4, rel=0.5)
    # 10 clips per source: the Laplace SDs carry the clips' spread (the variational
    # posterior's own SDs would not); the spread of a source's mean clip worth is
    # 0.5 / sqrt(10) = 0.16 alone.
    assert (scores["sd"] > 0.12).all()


def test_ranked_pairs_break_rankings_and_best_of_k_answers():
    rows = pd.DataFrame({"trial_key": [1, 1, 1, 2, 2, 2], "pcode": [0, 0, 0, 1, 1, 1],
                         "source": ["a", "b", "c", "a", "b", "c"],
                         "stimulus": [10, 20, 30, 11, 21, 31], "rank": [2, 1, 3, 2, 2, 1]})
    pairs = mixed.ranked_pairs(rows, "rank")
    # Trial 1 (all ranks differ) gives all three pairs; trial 2 (best c, the rest 2) two.
    assert len(pairs) == 5
    winners = np.where(pairs["won"] == 1, pairs["first"], pairs["second"])
    losers = np.where(pairs["won"] == 1, pairs["second"], pairs["first"])
    assert sorted(zip(pairs["trial"], winners, losers)) == [
        (1, "a", "c"), (1, "b", "a"), (1, "b", "c"), (2, "c", "a"), (2, "c", "b")]
    assert (pairs["first"] <= pairs["second"]).all()


def test_worth_model_is_skipped_unless_asked_for():
    table = simulate.simulate(WORTH_TYPES[0], STRENGTHS, participants=12, trials=4,
                              actions=("x",), clips_per_source=3, seed=0)
    names = {t.name for t in analyse(table, config(bootstrap=50)).analysis.tables}
    assert "mixed_model_worth" not in names
