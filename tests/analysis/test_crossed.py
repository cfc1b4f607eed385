"""The crossed bootstrap: participants and clips both random."""

import numpy as np
import pandas as pd
import pytest

from analysis import crossed, simulate
from analysis.pairwise import comparisons
from tests.analysis.conftest import config


def _rows(table):
    rows = table.assign(pcode=pd.factorize(table["participant"])[0],
                        trial_key=pd.factorize(table["trial_id"])[0])
    return rows.sort_values(["trial_key", "position"], kind="stable").reset_index(drop=True)


def test_draws_within_keep_each_group_its_size():
    groups = np.array([0, 0, 1, 1, 1, 2])
    counts = crossed.draws_within(groups, 50, np.random.default_rng(0))
    assert counts.shape == (50, 6)
    for g in range(3):
        assert np.all(counts[:, groups == g].sum(axis=1) == np.sum(groups == g))
    assert np.all(counts[:, 5] == 1)  # a group of one is always itself


def test_design_of_pairwise_trials():
    rows = _rows(simulate.simulate("pairwise", {"a": 0.0, "b": 0.0}, participants=6, trials=4,
                                   actions=("x", "y"), clips_per_source=3, seed=1))
    d = crossed.design(rows, unit="trial_key")
    assert d.n_units == 24 and d.clips.shape == (24, 2) and d.n_participants == 6
    assert d.clips_per_unit == 2.0
    assert np.all(d.clips_per_stratum <= 3) and d.n_strata == 4


def test_ratio_statistic_is_the_weighted_mean_per_group():
    values, groups = np.array([1.0, 3.0, 5.0, 7.0]), np.array([0, 0, 1, 1])
    statistic = crossed.ratio(values, groups, 2, base=np.array([1.0, 1.0, 1.0, 3.0]))
    assert statistic(np.ones((1, 4)))[0] == pytest.approx([2.0, (5 + 21) / 4])
    assert statistic(np.array([[2.0, 0.0, 1.0, 0.0]]))[0] == pytest.approx([1.0, 5.0])


def test_crossed_intervals_hold_where_participant_intervals_fail():
    # The case: equal sources, clip SD 1.5, 2 clips per source and action.
    covered = covered_by_participants = 0
    for seed in range(8):
        rows = _rows(simulate.simulate("pairwise", {"a": 0.0, "b": 0.0}, participants=60,
                                       trials=10, actions=("x", "y"), clips_per_source=2,
                                       clip_sd=1.5, tie_rate=0.0, seed=seed))
        trials = comparisons(rows, ["a", "b"])
        result = crossed.bootstrap(crossed.design(rows, unit="trial_key"),
                                   crossed.worth_statistic(np.stack([trials.winner, trials.loser], 1), 2),
                                   config(bootstrap=200, seed=seed))
        table = crossed.differences(result, ["a", "b"])
        covered += table["ci_low"][0] <= 0 <= table["ci_high"][0]
        low, high = result.contrast([[1.0, -1.0]]).percentile("participants")
        covered_by_participants += low[0] <= 0 <= high[0]
    assert covered >= 7
    assert covered_by_participants <= 4
    clips = crossed.clips_per_source(rows)
    assert clips.loc["a", "n_clips"] == 4 and clips.loc["a", "most_per_condition"] == 2
    assert table["share_clips"][0] > 0.5
    warning = crossed.clip_warnings(table, clips)
    assert warning and "about these 8 clips, not the method: add clips, not participants" in warning[0]


def test_differences_are_holm_corrected_t_tests():
    rng = np.random.default_rng(3)
    estimate = np.array([0.0, 1.0, 3.0])
    samples = estimate + rng.normal(0, 1, (400, 3))
    d = crossed.Design(np.arange(40) % 20, (np.arange(40) % 8)[:, None], np.arange(8) % 4,
                       np.arange(40) % 8)
    result = crossed.Crossed(estimate, samples, samples, np.zeros_like(samples), d)
    table = crossed.differences(result, ["x", "y", "z"])
    parts = result.contrast(crossed.pair_matrix(["x", "y", "z"])[0]).variances()
    assert table["se"].to_numpy() == pytest.approx(np.sqrt(parts["participants"]
                                                           + 2 * parts["clips"]))
    assert list(table["p_holm"]) == pytest.approx(list(crossed.holm(table["p"])))
    assert table["difference"].tolist() == pytest.approx([-1.0, -3.0, -2.0])


def test_single_clip_groups_are_named():
    d = crossed.Design(np.arange(4), np.array([[0], [1], [2], [2]]), np.array([0, 1, 1]),
                       np.array([0, 1, 2, 2]))
    assert "1 of 2 source-and-condition groups have a single clip" in crossed.one_clip_note(d)


def test_fixed_clips_give_intervals_over_participants_only():
    from analysis.study import analyse

    table = simulate.simulate("rating_standards", {"a": 0.0, "b": 0.0}, participants=40, trials=6,
                              actions=("x", "y"), clips_per_source=2, clip_sd=1.5, seed=2)
    random = analyse(table, config())
    fixed = analyse(table, config(random_clips=False))
    width = lambda result: (result.analysis.sources["ci_high"] - result.analysis.sources["ci_low"]).mean()
    assert width(fixed) < width(random) / 2
    assert "hold for these 8 clips" in fixed.methods()
    assert "treat participants and clips as random" in random.methods()
    assert any("add clips, not participants" in note for note in random.notes)
    assert not any("add clips, not participants" in note for note in fixed.notes)
    assert "treat participants and clips as random" not in fixed.methods()


@pytest.mark.parametrize("study_type", ["rating_standards", "pairwise"])
def test_the_coverage_benchmark_in_small(study_type):
    from benchmarks import bench_coverage

    args = bench_coverage.parse(["--studies", "10", "--bootstrap", "40", "--actions", "1",
                                 "--participants", "30", "--trials", "6"])
    result = bench_coverage.cell(study_type, 0.0, 1.5, 2, 0.0, args)
    # Equal sources, clips that vary: the intervals over participants alone call most
    # studies significant; over participants and clips, few.
    assert result["crossed"]["rejected"] <= 0.2
    assert result["participants"]["rejected"] >= 0.5
    assert result["crossed"]["coverage"] >= 0.8
    assert result["crossed"]["width"] > result["participants"]["width"]


def test_few_clip_degrees_of_freedom_are_named():
    d = crossed.Design(np.arange(8) % 4, (np.arange(8) % 4)[:, None], np.array([0, 0, 1, 1]),
                       np.arange(8) % 4)
    assert "rests on 2 degrees of freedom (4 clips in 2 source-and-condition groups)" in \
        crossed.one_clip_note(d)
    many = crossed.Design(np.arange(16) % 4, (np.arange(16) % 8)[:, None], np.arange(8) % 2,
                          np.arange(16) % 8)
    assert crossed.one_clip_note(many) is None


@pytest.mark.parametrize("study_type, unit", [("pairwise", "trial_key"), ("rating_standards", None)])
def test_sums_drawn_from_sufficient_statistics_match_unit_weights(study_type, unit):
    """A linear statistic's replicates drawn from per-participant, per-set-of-clips and
    per-distinct-answer sums have the mean and variance of those from unit weights."""
    rows = _rows(simulate.simulate(study_type, {"a": 0.6, "b": 0.0, "c": 0.2}, participants=30,
                                   trials=6, actions=("x",), clips_per_source=3, clip_sd=0.8,
                                   seed=3))
    d = crossed.design(rows, unit=unit)
    if unit is None:
        answer = rows["rating"].to_numpy(dtype=float)
        statistic = crossed.ratio(answer, pd.factorize(rows["source"], sort=True)[0], 3)
    else:
        trials = comparisons(rows, ["a", "b", "c"])
        statistic = crossed.worth_statistic(np.stack([trials.winner, trials.loser], 1), 3)
    assert isinstance(statistic, crossed.Linear)
    for scheme in ("participants", "clips", "observations"):
        fast = crossed._replicates(d, statistic, scheme, 3000, np.random.default_rng(0))
        slow = crossed._replicates(d, lambda w: statistic(w), scheme, 3000, np.random.default_rng(1))
        spread = slow.std(axis=0)
        assert fast.mean(axis=0) == pytest.approx(slow.mean(axis=0), abs=0.1 * spread.max() + 1e-9)
        # Standard deviations of 3000 replicates each agree within about 2 x 2.6 %.
        assert fast.std(axis=0) == pytest.approx(spread, rel=0.08, abs=1e-9)


def test_clip_degrees_of_freedom_come_from_the_sources_compared():
    # Four sources of 2 clips each (as a MUSHRA study with a hidden reference and an
    # anchor): a difference of two sources' means rests on their 4 clips (2 degrees of
    # freedom), not on all 8 (4); one source's mean on its own 2 clips (1).
    rows = simulate.simulate("rating_standards", {"a": 0.0, "b": 0.0, "c": 1.0, "d": -1.0},
                             participants=20, trials=8, actions=("x",), clips_per_source=2,
                             clip_sd=1.0, seed=4)
    rows = rows.assign(pcode=pd.factorize(rows["participant"])[0])
    result, groups = crossed.group_means(rows, "rating", config(bootstrap=50))
    assert list(groups) == ["a", "b", "c", "d"]
    assert result.clip_df().tolist() == [1.0, 1.0, 1.0, 1.0]
    assert result.contrast([[1.0, -1.0, 0.0, 0.0]]).clip_df().tolist() == [2.0]
    # Every difference takes the clips' 2, whether or not its clips' part came out 0.
    assert crossed.differences(result, list(groups))["df"].tolist() == [2.0] * 6
    assert result.summary()["df"].tolist() == [1.0] * 4
    # A fit over all sources (every value moves with every clip) keeps all of them: C - S.
    trials = simulate.simulate("pairwise", {"a": 0.0, "b": 0.0, "c": 0.5}, participants=20,
                               trials=8, actions=("x",), clips_per_source=2, clip_sd=1.0, seed=4)
    trials = _rows(trials)
    pairs = comparisons(trials, ["a", "b", "c"])
    worths = crossed.bootstrap(crossed.design(trials, unit="trial_key"),
                               crossed.worth_statistic(np.stack([pairs.winner, pairs.loser], 1), 3),
                               config(bootstrap=50))
    assert worths.contrast([[1.0, -1.0, 0.0]]).clip_df().tolist() == [3.0]


def test_few_clip_degrees_of_freedom_of_a_difference_are_named():
    # Eight sources of 2 clips: 8 clip degrees of freedom in all, but a difference of two
    # sources rests on their 4 clips (2).
    d = crossed.Design(np.arange(32) % 8, (np.arange(32) % 16)[:, None], np.arange(16) // 2,
                       np.arange(32) % 16)
    assert crossed.one_clip_note(d) is None
    assert "a difference rests on as few as 2 degrees of freedom" in crossed.one_clip_note(d, 2.0)
    assert crossed.one_clip_note(d, 14.0) is None



def _seeded_ratings(seed, seed_sd=1.0, seeds=3, clips=4, participants=30):
    """Ratings of two equal sources whose clips come from ``seeds`` checkpoints each, the
    checkpoints differing by ``seed_sd`` (a method's training varies) and clips little."""
    rng = np.random.default_rng(seed)
    clip_effects = []
    for source in ("a", "b"):
        for training_seed in range(seeds):
            shift = rng.normal(0, seed_sd)
            clip_effects += [(source, training_seed, shift + rng.normal(0, 0.2)) for _ in range(clips)]
    person = rng.normal(0, 0.5, participants)
    rows = [{"pcode": p, "stimulus": clip, "source": source, "action": "x",
             "training_seed": training_seed, "rating": effect + person[p] + rng.normal(0, 0.5)}
            for p in range(participants)
            for clip, (source, training_seed, effect) in enumerate(clip_effects)]
    return pd.DataFrame(rows)


def test_training_seeds_are_a_random_unit_of_the_clips_bootstrap():
    # Clips nest in their checkpoint; with several training seeds per source the clips'
    # bootstrap redraws whole seeds, so a difference rests on 2 + 2 seed degrees of
    # freedom and its interval covers where one over clips alone (which takes these
    # checkpoints as the method) does not.
    rows = _seeded_ratings(0)
    d = crossed.design(rows)
    assert d.n_seeds == 6 and d.n_resampled == 6 and list(d.units_per_stratum) == [3, 3]
    assert len(set(d.units[:4])) == 1 and d.units[0] != d.units[4]  # a seed's clips together
    assert crossed.design(rows.drop(columns="training_seed")).n_seeds == 0
    assert crossed.design(rows.assign(training_seed=0)).n_seeds == 0  # one seed: clips resampled
    covered = covered_without = 0
    for seed in range(10):
        rows = _seeded_ratings(seed)
        result, groups = crossed.group_means(rows, "rating", config(bootstrap=200, seed=seed))
        with_seeds = crossed.differences(result, list(groups))
        assert with_seeds["df"][0] == 4.0
        fixed, _ = crossed.group_means(rows.drop(columns="training_seed"), "rating",
                                       config(bootstrap=200, seed=seed))
        without = crossed.differences(fixed, list(groups))
        covered += with_seeds["ci_low"][0] <= 0 <= with_seeds["ci_high"][0]
        covered_without += without["ci_low"][0] <= 0 <= without["ci_high"][0]
    assert covered >= 9 and covered_without <= 7
    text = crossed.methods_text(result.design, config(bootstrap=200))
    assert "for the 2 sources whose clips come from several training seeds (3 each)" in text
    # A real source beside a seeded method keeps its clips as the resampled unit.
    mixed = pd.concat([rows[rows["source"] == "a"],
                       rows[rows["source"] == "b"].assign(training_seed=np.nan, source="real")])
    d = crossed.design(mixed)
    assert d.n_seeds == 3 and d.n_resampled == 3 + 12


def test_bench_crossed_noise_counts_the_answers_noise_in_the_clips_scheme(capsys):
    """The benchmark runs, and its point holds on a small table: with clips that do not
    vary, sets of four carry the answers' noise into V_c about 13 times (docs/STATISTICS.md)."""
    from benchmarks import bench_crossed_noise

    row = bench_crossed_noise.measure(4, 0.0, studies=2, units=800, participants=40,
                                      replicates=300)
    assert row["weight_variance"] > 13 and row["clips"] > 6 and row["width"] > 2
    bench_crossed_noise.main(["--studies", "1", "--units", "200", "--participants", "10",
                              "--replicates", "50", "--clip-sd", "0"])
    out = capsys.readouterr().out
    assert out.count("\n| ") == 3 and "nan" not in out  # a row per k
