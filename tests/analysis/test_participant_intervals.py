"""Intervals over participants: the shared bootstrap, its behaviour on judgements that are
alike within a participant, and the note on too few participants."""

import numpy as np
import pandas as pd
import pytest
from scipy.special import expit

from analysis import stats, worth
from analysis.report import write_report
from analysis.study import analyse
from tests.analysis.conftest import config, make_table, trial

SOURCES = ("real", "a2m")


def correlated_table(rng, n_participants=40, per_participant=30, spread=2.0):
    """Return fake-or-real answers where each participant has their own tendency to say
    "real": p_i = expit(a_i), a_i ~ N(0, spread). By symmetry the population's share is 0.5
    exactly, for every source; judgements of one participant are strongly alike."""
    leaning = rng.normal(0.0, spread, n_participants)
    rows = []
    for p in range(n_participants):
        real = rng.random(per_participant) < expit(leaning[p])
        for j, value in enumerate(real):
            rows.append({"pcode": p, "source": SOURCES[j % 2], "judged_real": float(value)})
    return pd.DataFrame(rows)


def test_participant_interval_is_wider_than_the_judgement_one_and_covers_the_truth():
    rng = np.random.default_rng(7)
    covered_participants = covered_judgements = wider = 0
    studies = 25
    for _ in range(studies):
        table = correlated_table(rng)
        shares = stats.bootstrap_means(table, "judged_real", n=200, seed=int(rng.integers(1e6)))
        counts = table.groupby("source")["judged_real"].agg(["sum", "size"])
        low, high = (pd.Series(v, index=counts.index)
                     for v in stats.wilson_interval(counts["sum"], counts["size"]))
        for source in SOURCES:
            row = shares.loc[source]
            covered_participants += row["ci_low"] <= 0.5 <= row["ci_high"]
            covered_judgements += low[source] <= 0.5 <= high[source]
            wider += (row["ci_high"] - row["ci_low"]) > (high[source] - low[source])
    n = studies * len(SOURCES)
    # Judgements treated as independent: far too narrow, the truth often outside.
    assert wider == n
    assert covered_participants >= 0.85 * n
    assert covered_judgements <= 0.75 * n
    assert covered_participants > covered_judgements


def test_the_study_analysis_gives_participant_intervals():
    rng = np.random.default_rng(3)
    table = correlated_table(rng, n_participants=30, per_participant=20)
    trials = [trial(f"p{p}", [(row.source, bool(row.judged_real), f"{row.source}-{i}")
                              for i, row in enumerate(group.itertuples())])
              for p, group in table.groupby("pcode")]
    result = analyse(make_table("fake_or_real", trials), config())
    sources = result.analysis.sources
    counts = table.groupby("source")["judged_real"].agg(["sum", "size"])
    for source in SOURCES:
        low, high = stats.wilson_interval(counts.loc[source, "sum"], counts.loc[source, "size"])
        row = sources.loc[source]
        assert row["ci_low"] <= 0.5 <= row["ci_high"]
        assert row["ci_high"] - row["ci_low"] > 1.5 * (high - low)
    assert "treat participants and clips as random" in result.methods()
    assert not any("fewer than" in note for note in result.notes)


def test_independent_judgements_give_about_the_judgement_interval():
    rng = np.random.default_rng(5)
    table = correlated_table(rng, n_participants=60, per_participant=20, spread=0.0)
    shares = stats.bootstrap_means(table, "judged_real", n=400)
    counts = table.groupby("source")["judged_real"].agg(["sum", "size"])
    low, high = stats.wilson_interval(counts["sum"], counts["size"])
    width = shares["ci_high"] - shares["ci_low"]
    assert width.to_numpy() == pytest.approx(high - low, rel=0.25)


def test_bootstrap_keeps_the_statistics_shape_and_renumbers_participants():
    rows = pd.DataFrame({"pcode": [5, 5, 9, 9, 2], "x": [1.0, 2.0, 3.0, 4.0, 5.0],
                         "g": ["a", "b", "a", "b", "a"]})
    score, low, high = stats.participant_bootstrap(rows, lambda t: t["x"].mean(), n=50)
    assert isinstance(score, float) and score == pytest.approx(3.0) and low <= score <= high
    # A participant drawn twice counts as two: every replicate has three participants.
    seen = stats.participant_bootstrap(rows, lambda t: t["pcode"].nunique(), n=50)
    assert seen == (3.0, 3.0, 3.0)
    score, low, high = stats.participant_bootstrap(rows, lambda t: t.groupby("g")["x"].mean(), n=50)
    assert list(score.index) == list(low.index) == ["a", "b"] and (low <= high).all()
    values, low, high = stats.participant_bootstrap(rows, lambda t: np.array([t["x"].min(), t["x"].max()]), n=5)
    assert values.shape == low.shape == (2,)


def test_the_fast_ratio_bootstrap_equals_the_general_one():
    rng = np.random.default_rng(2)
    table = correlated_table(rng, n_participants=15, per_participant=6)
    table["rating"] = rng.integers(1, 6, len(table)).astype(float)
    general = stats.participant_bootstrap(
        table, lambda t: t.groupby("source")["rating"].mean(), n=60, seed=9)
    fast = stats.bootstrap_means(table, "rating", n=60, seed=9)
    for got, expected in zip((fast["score"], fast["ci_low"], fast["ci_high"]), general):
        assert got.to_numpy() == pytest.approx(expected.reindex(got.index).to_numpy())
    # Undefined ratios (a group no participant drawn judged) are left out, not counted as 0.
    numerator = np.array([[1.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
    denominator = np.array([[1.0, 1.0], [1.0, 0.0], [1.0, 0.0]])
    score, low, high = stats.ratio_bootstrap(numerator, denominator, n=200)
    assert score == pytest.approx([2 / 3, 0.0])
    assert (low[1], high[1]) == (0.0, 0.0) and 0 <= low[0] <= high[0] <= 1


def test_bootstrap_without_resamples_or_participants_has_no_interval():
    rows = pd.DataFrame({"pcode": [1, 1], "x": [1.0, 2.0]})
    assert np.isnan(stats.participant_bootstrap(rows, lambda t: t["x"].mean(), n=100)[1])
    two = pd.DataFrame({"pcode": [1, 2], "x": [1.0, 2.0]})
    assert np.isnan(stats.participant_bootstrap(two, lambda t: t["x"].mean(), n=0)[2])


def test_draws_are_those_of_the_worth_bootstrap():
    draws = stats.participant_draws(7, 20, seed=4)
    counts = np.stack([np.bincount(d, minlength=7) for d in draws])
    assert np.array_equal(counts, worth.resample_participants(7, 20, seed=4))


def test_few_participants_get_a_note_in_the_report(tmp_path):
    table = make_table("rating_standards", [
        trial(p, [("real", 5 - p % 2), ("a2m", 3), ("gru", 1 + p % 2)]) for p in range(4)])
    result = analyse(table, config())
    note = next(n for n in result.notes if "fewer than" in n)
    assert f"fewer than {stats.MIN_PARTICIPANTS}" in note and "only 4 participant" in note
    assert "these intervals are rough" in result.methods()
    write_report(result, tmp_path)
    assert note in (tmp_path / "report.html").read_text()
    many = make_table("rating_standards", [
        trial(p, [("real", 5 - p % 2), ("a2m", 3), ("gru", 1 + p % 2)])
        for p in range(stats.MIN_PARTICIPANTS)])
    assert not any("fewer than" in n for n in analyse(many, config()).notes)
