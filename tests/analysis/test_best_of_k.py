"""Best of K: Plackett-Luce top-1 worths against the likelihood, all good / all bad shares,
strengths of simulated participants recovered, bad tables refused."""

import numpy as np
import pandas as pd
import pytest
from scipy import optimize
from scipy import stats as scipy_stats

from analysis.best_of_k import Choices, fit_top1, log_likelihood
from analysis.simulate import simulate
from analysis.study import analyse
from analysis.tables import RESPONSE_COLUMNS, AnalysisError
from tests.analysis.conftest import config

STRENGTHS = {"real": 4.0, "a2m": 3.0, "two_stage_gan": 2.0, "cond_gru": 1.0}
TRUE_ORDER = ["real", "a2m", "two_stage_gan", "cond_gru"]


def table_of(trials):
    """Return a response table of ``trials``: ``(participant, [sources], pick)`` with
    ``pick`` the position picked or ``all_good`` / ``all_bad``."""
    rows = []
    for trial_id, (participant, sources, pick) in enumerate(trials, start=1):
        for position, source in enumerate(sources):
            row = dict.fromkeys(RESPONSE_COLUMNS)
            answer = pick if isinstance(pick, str) else ("best" if pick == position else "other")
            row.update(study="test", study_type="best_of_k", participant=participant,
                       trial=trial_id, trial_id=trial_id, action="walk",
                       stimulus=f"{source}-{trial_id % 3}", source=source, position=position,
                       n_items=len(sources), trial_kind="main", is_catch=False, time_ms=9000,
                       duration=2.0, completed=True, pick=answer)
            rows.append(row)
    return pd.DataFrame(rows, columns=list(RESPONSE_COLUMNS) + ["pick"])


def test_the_mm_fit_is_the_maximum_of_the_top1_likelihood():
    rng = np.random.default_rng(3)
    true = np.array([1.0, 0.4, 0.0, -1.2])
    shown, chosen = np.zeros((600, 4), int), np.zeros(600, int)
    for t in range(600):
        seats = rng.choice(4, 3, replace=False)
        if t % 5 == 0:
            seats[2] = seats[0]  # a source shown twice counts twice
        np.add.at(shown[t], seats, 1)
        p = np.exp(true[seats]) / np.exp(true[seats]).sum()
        chosen[t] = rng.choice(seats, p=p)
    choices = Choices(shown, chosen, np.arange(600) % 20, 4, 20)
    theta = fit_top1(choices.sets, choices.one_hot, choices.counts.sum(axis=0), prior=0)[0]
    counts = choices.counts.sum(axis=0)
    best = optimize.minimize(lambda x: -log_likelihood(choices.sets, choices.chosen, counts, x),
                             np.zeros(4), method="BFGS")
    assert theta == pytest.approx(best.x - best.x.mean(), abs=1e-4)
    assert theta.sum() == pytest.approx(0.0, abs=1e-9)
    # The prior pulls towards 0 but keeps the order.
    shrunk = fit_top1(choices.sets, choices.one_hot, counts)[0]
    assert list(np.argsort(shrunk)) == list(np.argsort(theta))
    assert np.abs(shrunk).max() < np.abs(theta).max()


def test_a_source_never_picked_keeps_a_finite_worth():
    trials = [(p, ["real", "a2m", "gru"], 0) for p in range(1, 4)]
    result = analyse(table_of(trials), config(bootstrap=50))
    sources = result.analysis.sources
    assert list(sources.index[:1]) == ["real"]
    assert np.isfinite(sources["score"]).all()
    assert sources.loc["real", "best_share"] == 1.0 and sources.loc["gru", "best_share"] == 0.0


def test_all_good_and_all_bad_are_shares_outside_the_fit():
    trials = [(1, ["real", "a2m", "gru"], 0), (1, ["gru", "real", "a2m"], 1),
              (2, ["a2m", "gru", "real"], 2), (2, ["real", "gru", "a2m"], "all_good"),
              (3, ["a2m", "real", "gru"], "all_bad"), (3, ["gru", "a2m", "real"], 1)]
    result = analyse(table_of(trials), config(bootstrap=50))
    answers = {t.name: t.frame for t in result.analysis.tables}["answers"].set_index("answer")
    assert answers["trials"].to_dict() == {"pick": 4, "all_good": 1, "all_bad": 1}
    assert answers.loc["all_good", "share"] == pytest.approx(1 / 6)
    sources = result.analysis.sources
    assert sources.loc["real", "all_good_share"] == pytest.approx(1 / 6)
    assert sources.loc["real", "best_share"] == pytest.approx(3 / 4)
    assert any("fewer than 10" in note for note in result.notes)
    assert 'all good' in " ".join(result.analysis.methods)


def test_bots_with_known_strengths_are_recovered_with_intervals_over_participants():
    table = simulate("best_of_k", STRENGTHS, participants=200, trials=8, clips_per_trial=4,
                     tie_rate=0.1, seed=11)
    result = analyse(table, config(bootstrap=200))
    sources = result.analysis.sources
    tau = scipy_stats.kendalltau([TRUE_ORDER.index(s) for s in sources.index], range(4)).statistic
    assert tau >= 0.9, list(sources.index)
    assert (sources["ci_low"] <= sources["score"]).all() and (sources["score"] <= sources["ci_high"]).all()
    # Worth differences follow the strengths' (one unit apart), within sampling error.
    gaps = -np.diff(sources.loc[TRUE_ORDER, "score"].to_numpy())
    assert gaps == pytest.approx([1.0, 1.0, 1.0], abs=0.35)
    assert not any("fewer than 10" in note for note in result.notes)
    # With a few participants the intervals widen, and the report says why.
    few = analyse(table.loc[table["participant"] <= 5], config(bootstrap=200))
    assert any("only 5 participant(s)" in note for note in few.notes)
    width = (sources["ci_high"] - sources["ci_low"]).mean()
    assert (few.analysis.sources["ci_high"] - few.analysis.sources["ci_low"]).mean() > 2 * width


@pytest.mark.parametrize("pick, message", [
    ("maybe", "none of best, other, all_good, all_bad"),
    ("best", "no single clip picked"),
])
def test_a_table_with_bad_picks_is_refused(pick, message):
    table = table_of([(1, ["real", "a2m"], 0), (2, ["a2m", "real"], 1)])
    table.loc[1, "pick"] = pick
    with pytest.raises(AnalysisError, match=message):
        analyse(table, config(bootstrap=0))


def test_simulated_trials_pick_one_clip_or_call_all_good_or_bad():
    table = simulate("best_of_k", participants=6, trials=4, catch_trials=1, repeat_trials=2, seed=1)
    main = table.loc[table["trial_kind"] == "main"]
    verdicts = main.groupby("trial_id")["pick"].apply(lambda p: tuple(sorted(set(p))))
    assert set(verdicts) <= {("best", "other"), ("all_good",), ("all_bad",)}
