"""Rank shares and the ranking study analysis against counts done by hand, errors, figure."""

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from analysis import worth
from analysis.figures import plot_rank_shares
from analysis.ranking import rank_columns, rank_shares, top_share
from analysis.stats import wilson_interval
from analysis.study import analyse
from analysis.tables import AnalysisError, read_responses, write_responses
from tests.analysis.conftest import config, make_table, trial

# participant, trial, action, {source: rank}
TRIALS = [
    (1, 0, "eat", {"real": 1, "a2m": 2, "gru": 3}),
    (1, 1, "walk", {"a2m": 1, "real": 2, "gru": 3}),
    (2, 0, "eat", {"real": 1, "gru": 2, "a2m": 3}),
    (2, 1, "walk", {"real": 1, "a2m": 2, "gru": 3}),
    (3, 0, "eat", {"a2m": 1, "real": 2, "gru": 3}),
    (3, 1, "walk", {"gru": 1, "real": 2, "a2m": 3}),
]
RANKS = ["rank_1", "rank_2", "rank_3"]


def response_table(trials=TRIALS):
    """Return a response table with one row per (trial, source) of ``trials``."""
    rows = []
    for participant, index, action, ranks in trials:
        for position, (source, rank) in enumerate(ranks.items()):
            rows.append(
                {
                    "participant": participant,
                    "trial": index,
                    "trial_id": participant * 10 + index,
                    "action": action,
                    "source": source,
                    "position": position,
                    "n_items": len(ranks),
                    "rank": rank,
                }
            )
    return pd.DataFrame(rows)


def test_rank_shares_match_hand_counts():
    shares = rank_shares(response_table())
    # real: ranks 1,2,1,1,2,2; a2m: 2,1,3,2,1,3; gru: 3,3,2,3,3,1.
    expected = pd.DataFrame(
        {
            "rank_1": [3 / 6, 2 / 6, 1 / 6],
            "rank_2": [3 / 6, 2 / 6, 1 / 6],
            "rank_3": [0 / 6, 2 / 6, 4 / 6],
            "n_judgements": [6, 6, 6],
            "n_participants": [3, 3, 3],
            "mean_rank": [1.5, 2.0, 2.5],
        },
        index=pd.Index(["real", "a2m", "gru"], name="source"),
    )
    pd.testing.assert_frame_equal(shares, expected, check_dtype=False, check_index_type=False)
    assert shares.attrs["n_participants"] == 3
    assert shares.attrs["n_judgements"] == 18
    assert shares.attrs["notes"] == []
    assert top_share(shares, 2).tolist() == pytest.approx([1.0, 4 / 6, 2 / 6])


def test_rank_shares_by_action_match_hand_counts():
    shares = rank_shares(response_table(), by_action=True)
    assert shares.index.names == ["action", "source"]
    eat = shares.xs("eat")
    assert list(eat.index) == ["real", "a2m", "gru"]
    assert eat.loc["real", RANKS].tolist() == pytest.approx([2 / 3, 1 / 3, 0])
    assert eat.loc["gru", "mean_rank"] == pytest.approx(8 / 3)
    walk = shares.xs("walk")
    assert list(walk.index) == ["real", "a2m", "gru"]
    assert walk.loc["gru", RANKS].tolist() == pytest.approx([1 / 3, 0, 2 / 3])
    assert walk["n_judgements"].tolist() == [3, 3, 3]


def test_missing_columns_are_named():
    table = response_table().drop(columns=["source", "n_items"])
    with pytest.raises(AnalysisError, match="source, n_items"):
        rank_shares(table)
    with pytest.raises(AnalysisError, match="action"):
        rank_shares(response_table().drop(columns=["action"]), by_action=True)


def test_rank_outside_its_trial_is_rejected():
    table = response_table()
    table.loc[0, "rank"] = 4
    with pytest.raises(AnalysisError, match="outside 1..n_items"):
        rank_shares(table)


def test_unranked_rows_are_ignored_and_empty_tables_rejected():
    table = response_table()
    table["rank"] = table["rank"].astype("Int64")
    table.loc[table["participant"] == 3, "rank"] = pd.NA
    assert rank_shares(table).attrs["n_judgements"] == 12
    with pytest.raises(AnalysisError, match="no ranked judgements"):
        rank_shares(table.iloc[0:0])


def test_trials_of_different_sizes_use_the_largest_and_say_so():
    trials = TRIALS + [(4, 0, "eat", {"real": 1, "a2m": 2, "gru": 3, "extra": 4})]
    shares = rank_shares(response_table(trials))
    assert rank_columns(shares) == ["rank_1", "rank_2", "rank_3", "rank_4"]
    assert shares.loc["extra", "rank_4"] == 1.0
    assert shares.loc["real", "rank_4"] == 0.0
    assert shares.attrs["n_items"] == [3, 4]
    assert "3 to 4 clips" in shares.attrs["notes"][0]


def test_one_source_is_noted():
    table = response_table([(1, 0, "eat", {"real": 1}), (2, 0, "eat", {"real": 1})])
    assert "only one source" in rank_shares(table).attrs["notes"][0]


def test_plot_writes_a_valid_png_and_svg(tmp_path):
    path = tmp_path / "fig" / "shares.png"
    written = plot_rank_shares(rank_shares(response_table()), path, svg=True)
    assert [p.name for p in written] == ["shares.png", "shares.svg"]
    with Image.open(written[0]) as image:
        assert image.format == "PNG"
        assert image.width > 300 and image.height > 100
    assert "Rank 1 (best)" in written[1].read_text()


def test_plot_rejects_a_table_by_action(tmp_path):
    with pytest.raises(AnalysisError, match="one action"):
        plot_rank_shares(rank_shares(response_table(), by_action=True), tmp_path / "x.png")


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_response_table_round_trip(tmp_path, suffix):
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    table = response_table()
    back = read_responses(write_responses(table, tmp_path / f"responses{suffix}"))
    pd.testing.assert_frame_equal(rank_shares(back), rank_shares(table), check_dtype=False)


# The study analysis of the same trials (participants' mean ranks worked out in
# tests/analysis/test_stats.py::test_friedman_corrects_for_ties).
def ranking_study():
    return make_table("ranking", [
        trial(participant, list(ranks.items()), action=action)
        for participant, _, action, ranks in TRIALS
    ])


def test_study_statistics_match_hand_counts():
    result = analyse(ranking_study(), config())
    sources = result.analysis.sources
    assert list(sources.index) == ["real", "a2m", "gru"]
    assert sources["mean_rank"].tolist() == pytest.approx([1.5, 2.0, 2.5])
    assert sources["top_1"].tolist() == pytest.approx([3 / 6, 2 / 6, 1 / 6])
    assert sources["top_2"].tolist() == pytest.approx([1.0, 4 / 6, 2 / 6])
    assert sources["n_judgements"].tolist() == [6, 6, 6]
    assert sources["n_participants"].tolist() == [3, 3, 3]
    friedman = result.analysis.tests["friedman"]
    assert friedman["statistic"] == pytest.approx(3.0) and friedman["n_blocks"] == 3
    assert result.analysis.tests["kendall_w"] == pytest.approx(0.5)
    expected = {"participants": 3, "judgements": 18, "trials": 6, "actions": 2,
                "sources": ["a2m", "gru", "real"], "participants_before": 3, "simulated": 0,
                "catch_trials": 0, "instructed_trials": 0, "repeat_trials": 0}
    assert {name: result.counts[name] for name in expected} == expected


def test_rank_share_intervals_are_over_participants_and_clips():
    tables = {t.name: t.frame for t in analyse(ranking_study(), config()).tables}
    shares = tables["rank_share_intervals"].set_index(["source", "rank"])
    # real is ranked first by P1 in 1 of 2 trials, P2 in 2 of 2, P3 in 0 of 2. A resample
    # of three participants is all P3 (share 0) or all P2 (share 1) with chance 1/27 each,
    # more than the 2.5 % in each tail: the interval is [0, 1] (Wilson over the six
    # judgements, as if independent, would be [0.19, 0.81]).
    assert shares.loc[("real", 1), ["share", "ci_low", "ci_high"]].tolist() == pytest.approx([0.5, 0, 1])
    assert wilson_interval(3, 6)[0] > 0.1
    assert shares.loc[("gru", 3), "count"] == 4 and shares.loc[("gru", 3), "n_judgements"] == 6
    differences = tables["differences"]
    assert len(differences) == 3 and differences["p_holm"].ge(differences["p"]).all()
    assert "pairwise_tests" not in tables


def test_worth_is_the_plackett_luce_fit_of_the_trials():
    result = analyse(ranking_study(), config())
    names = ["a2m", "gru", "real"]
    orders = [[names.index(s) for s, _ in sorted(r.items(), key=lambda kv: kv[1])] for *_, r in TRIALS]
    expected = dict(zip(names, worth.fit(np.array(orders), np.ones(len(orders)), 3)))
    scores = result.analysis.sources["score"]
    assert scores.to_dict() == pytest.approx(expected)
    assert (result.analysis.sources["ci_low"] <= scores).all()
    assert result.summary()["order"] == ["real", "a2m", "gru"]


def test_ranking_agreement_is_ordinal_over_stimuli():
    krippendorff = pytest.importorskip("krippendorff")
    table = ranking_study()
    result = analyse(table, config())
    matrix = table.pivot_table(index="participant", columns="stimulus", values="rank", aggfunc="first")
    expected = krippendorff.alpha(reliability_data=matrix.to_numpy(dtype=float),
                                  level_of_measurement="ordinal")
    assert result.agreement["level"] == "ordinal" and result.agreement["n_units"] == 6
    assert result.agreement["alpha"] == pytest.approx(expected)


def test_catch_clips_are_dropped_and_ranks_renumbered():
    trials = [trial(1, [("real", 1), ("catch", 2), ("a2m", 3)]),
              trial(2, [("a2m", 1), ("real", 2), ("catch", 3)])]
    result = analyse(make_table("ranking", trials), config())
    shares = {t.name: t.frame for t in result.tables}["rank_shares"]
    assert set(shares.index) == {"real", "a2m"}
    assert shares.loc["real", ["rank_1", "rank_2"]].tolist() == [0.5, 0.5]


def test_tied_ranks_are_refused():
    trials = [trial(1, [("real", 1), ("a2m", 1)]), trial(2, [("real", 1), ("a2m", 2)])]
    with pytest.raises(AnalysisError, match="1 trial\\(s\\) give two clips the same rank"):
        analyse(make_table("ranking", trials), config())


def test_simulated_trials_rank_every_clip_once():
    from analysis.simulate import simulate

    table = simulate("ranking", participants=6, trials=4, catch_trials=1, repeat_trials=2, seed=1)
    main = table.loc[table["trial_kind"] == "main"]
    assert set(main.groupby("trial_id")["rank"].apply(lambda r: tuple(sorted(r)))) == {(1, 2, 3)}
