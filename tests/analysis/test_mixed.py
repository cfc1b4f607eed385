"""Mixed models with crossed random intercepts (statsmodels) beside the crossed bootstrap."""

import numpy as np
import pandas as pd
import pytest

from analysis import mixed, simulate
from analysis.study import analyse
from tests.analysis.conftest import config


def test_linear_model_agrees_with_the_crossed_bootstrap_on_ratings():
    table = simulate.simulate("rating_standards", {"a": 0.0, "b": 1.0}, participants=40, trials=6,
                              actions=("x", "y"), clips_per_source=4, clip_sd=1.0, seed=4)
    result = analyse(table, config(mixed_models=True))
    tables = {t.name: t.frame for t in result.analysis.tables}
    ours = tables["differences"].set_index(["a", "b"]).loc[("a", "b")]
    model = tables["mixed_model"].set_index(["a", "b"]).loc[("a", "b")]
    # Clips are drawn at random per trial, so some are shown more often: the model weighs
    # them by how much they tell (GLS), the sample means by how often they were shown;
    # the two differences are close, and so are their standard errors.
    assert model["difference"] == pytest.approx(ours["difference"], abs=0.1)
    assert model["se"] == pytest.approx(ours["se"], rel=0.4)
    components = tables["variance_components"].set_index("component")
    assert components.loc["clips", "variance"] > components.loc["participants", "variance"]
    assert components["share"].sum() == pytest.approx(1.0)
    assert "MixedLM" in result.methods()


def test_linear_model_recovers_known_components():
    rng = np.random.default_rng(0)
    participants, clips = 30, 12
    p_effect, c_effect = rng.normal(0, 1.0, participants), rng.normal(0, 0.5, clips)
    rows = [{"pcode": p, "stimulus": c, "source": "ab"[c % 2],
             "y": 1.0 * (c % 2) + p_effect[p] + c_effect[c] + rng.normal(0, 0.7)}
            for p in range(participants) for c in range(clips)]
    fitted = mixed.linear(pd.DataFrame(rows), "y")
    components = fitted["components"].set_index("component")["sd"]
    assert components["participants"] == pytest.approx(1.0, rel=0.35)
    assert components["clips"] == pytest.approx(0.5, rel=0.6)
    assert components["residual"] == pytest.approx(0.7, rel=0.15)
    # lme4 gives the same on this design; statsmodels' estimate of b - a by hand:
    frame = pd.DataFrame(rows)
    by_hand = frame.loc[frame.source == "b", "y"].mean() - frame.loc[frame.source == "a", "y"].mean()
    assert -fitted["differences"].iloc[0]["difference"] == pytest.approx(by_hand, abs=1e-6)


def test_logistic_model_of_fake_or_real():
    table = simulate.simulate("fake_or_real", {"real": 1.5, "a": 0.0}, participants=30, trials=6,
                              actions=("x",), clips_per_source=6, clip_sd=1.0, clips_per_trial=2,
                              seed=1)
    result = analyse(table, config(mixed_models=True, bootstrap=100))
    tables = {t.name: t.frame for t in result.analysis.tables}
    model = tables["mixed_model"].set_index("a").loc["a"]
    shares = result.analysis.sources["score"]
    empirical = np.log(shares["a"] / (1 - shares["a"])) - np.log(shares["real"] / (1 - shares["real"]))
    # The model's log-odds difference is conditional on the intercepts: larger in size than
    # the marginal one, of the same sign.
    assert model["log_odds_difference"] < 0 and abs(model["log_odds_difference"]) >= 0.8 * abs(empirical)
    assert model["ci_low"] < model["log_odds_difference"] < model["ci_high"]
    assert "BinomialBayesMixedGLM" in result.methods()
    # The bootstrap compares sources by their clips' mean log-odds (each clip's empirical
    # log-odds), the scale of the model's conditional log-odds: the two estimates agree,
    # and the model's SD carries the clips' spread as the bootstrap's standard error does
    # (the mean-field variational SD was a third of it here).
    differences = result.analysis.tests["differences"]
    row = differences.loc[(differences["a"] == "a") & (differences["b"] == "real")].iloc[0]
    assert row["difference"] == pytest.approx(model["log_odds_difference"], abs=0.4)
    assert result.analysis.sources.loc["a", "log_odds_difference"] == pytest.approx(row["difference"])
    assert 0.5 < model["sd"] / row["se"] < 2.0
    # With 6 clips per source in one condition the Wald test takes the clips' 10 degrees
    # of freedom (the participants' 29 are more).
    assert model["df"] == 10


def test_models_are_skipped_when_not_asked_for_or_too_large(monkeypatch):
    table = simulate.simulate("mushra", {"a": 0.0, "b": 1.0}, participants=12, trials=3,
                              actions=("x",), clips_per_source=3, seed=0)
    assert "mixed_model" not in {t.name for t in analyse(table, config()).analysis.tables}
    monkeypatch.setattr(mixed, "MAX_DESIGN", 10)
    result = analyse(table, config(mixed_models=True))
    assert "mixed_model" not in {t.name for t in result.analysis.tables}
    assert any("the crossed bootstrap stands alone" in note for note in result.notes)
