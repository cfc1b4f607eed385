"""MUSHRA: per-participant means against hand counts, the post-screening rule (its
threshold an option), strengths of simulated participants recovered, bad tables refused."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats as scipy_stats

from analysis.simulate import simulate
from analysis.study import analyse
from analysis.tables import RESPONSE_COLUMNS, AnalysisError
from tests.analysis.conftest import config

STRENGTHS = {"real": 4.0, "a2m": 3.0, "two_stage_gan": 2.0, "cond_gru": 1.0}
TRUE_ORDER = ["real", "a2m", "two_stage_gan", "cond_gru"]
RULE = "Scored the hidden reference below {} in more than {:.0%} of trials (MUSHRA post-screening)"


def table_of(trials):
    """Return a response table of ``trials``: ``(participant, {clip: score})``, clips
    ``real``/``a2m`` (judged), ``ref`` (the hidden reference, a real clip) and ``anchor``."""
    rows = []
    for trial_id, (participant, scores) in enumerate(trials, start=1):
        for position, (clip, score) in enumerate(scores.items()):
            row = dict.fromkeys(RESPONSE_COLUMNS)
            role = {"ref": "reference", "anchor": "anchor"}.get(clip, "judged")
            row.update(study="test", study_type="mushra", participant=participant,
                       trial=trial_id, trial_id=trial_id, action="walk",
                       stimulus=f"{clip}-{trial_id % 2}", source="real" if clip == "ref" else clip,
                       position=position, n_items=len(scores), trial_kind="main", is_catch=False,
                       time_ms=9000, duration=2.0, completed=True, stimulus_role=role, score=score)
            rows.append(row)
    return pd.DataFrame(rows, columns=list(RESPONSE_COLUMNS) + ["stimulus_role", "score"])


TRIALS = [
    (1, {"real": 80, "a2m": 60, "ref": 100, "anchor": 10}),
    (1, {"real": 70, "a2m": 40, "ref": 95, "anchor": 20}),
    (2, {"real": 90, "a2m": 30, "ref": 92, "anchor": 0}),
    (2, {"real": 50, "a2m": 50, "ref": 100, "anchor": 30}),
    (3, {"real": 60, "a2m": 70, "ref": 99, "anchor": 5}),
    (3, {"real": 65, "a2m": 45, "ref": 91, "anchor": 15}),
]


def test_a_condition_scores_the_mean_of_participants_means():
    result = analyse(table_of(TRIALS), config())
    sources = result.analysis.sources
    assert list(sources.index) == ["hidden_reference", "real", "a2m", "anchor"]
    assert sources.loc["real", "score"] == pytest.approx(np.mean([75, 70, 62.5]))
    assert sources.loc["a2m", "score"] == pytest.approx(np.mean([50, 40, 57.5]))
    assert sources.loc["hidden_reference", "condition"] == "hidden reference"
    assert sources.loc["anchor", "condition"] == "low anchor"
    assert sources.loc["real", "n_judgements"] == 6  # the reference is not pooled with real
    assert (sources["ci_low"] <= sources["score"]).all() and (sources["score"] <= sources["ci_high"]).all()
    tests = {t.name: t.frame for t in result.analysis.tables}["differences"].set_index(["a", "b"])
    assert tests.loc[("a2m", "real"), "difference"] == pytest.approx(np.mean([50, 40, 57.5])
                                                                     - np.mean([75, 70, 62.5]))
    assert tests.loc[("a2m", "real"), "p"] < 1
    assert tests["p_holm"].between(0, 1).all() and (tests["p_holm"] >= tests["p"]).all()
    assert "pairwise_tests" not in {t.name for t in result.analysis.tables}


def test_post_screening_excludes_who_misses_the_hidden_reference_in_over_15_percent():
    # Participant 4 scores the hidden reference below 90 in 1 of 6 trials (17 %): out.
    # Participant 5 in 1 of 7 (14 %): kept. Both score a2m above real.
    trials = list(TRIALS)
    for participant, trials_of, low in ((4, 6, 1), (5, 7, 1)):
        for k in range(trials_of):
            trials.append((participant, {"real": 20, "a2m": 90, "ref": 85 if k < low else 95,
                                         "anchor": 10}))
    result = analyse(table_of(trials), config())
    rule = result.exclusions.set_index("rule").loc[RULE.format(90, 0.15)]
    assert rule["applied"] == "yes" and rule["participants"] == 1 and rule["trials"] == 6
    analysed = result.exclusions.set_index("rule").loc["Analysed"]
    assert analysed["participants"] == 4 and analysed["judgements"] == (6 + 7) * 4
    assert result.counts["participants"] == 4
    screening = {t.name: t.frame for t in result.analysis.tables}["post_screening"]
    assert screening.set_index("participant")["excluded"].to_dict() == {
        1: False, 2: False, 3: False, 4: True, 5: False}
    assert "below 90 in more than 15% of trials" in " ".join(result.analysis.methods)
    # The study's options move the threshold and the share; --no-exclusions counts only.
    strict = analyse(table_of(trials), config(type_options={"screen_threshold": 93}))
    excluded = strict.exclusions.set_index("rule").loc[RULE.format(93, 0.15), "participants"]
    assert excluded == 3  # participants 2 (92) and 3 (91) in 1 of 2 trials, and 4
    lenient = analyse(table_of(trials), config(type_options={"screen_share": 0.2}))
    assert lenient.exclusions.set_index("rule").loc[RULE.format(90, 0.2), "participants"] == 0
    off = analyse(table_of(trials), config(exclusions=False))
    row = off.exclusions.set_index("rule").loc[RULE.format(90, 0.15)]
    assert row["applied"] == "no (--no-exclusions)" and row["participants"] == 1
    assert off.counts["participants"] == 5


def test_simulated_participants_are_recovered_and_inattentive_ones_screened_out():
    """200 simulated participants, 10 % answering at random, no catch trials: the
    post-screening alone finds the random raters."""
    table = simulate("mushra", STRENGTHS, participants=200, trials=8, inattentive=0.1, seed=5)
    result = analyse(table, config(bootstrap=200))
    sources = result.analysis.sources
    order = [s for s in sources.index if s in TRUE_ORDER]
    tau = scipy_stats.kendalltau([TRUE_ORDER.index(s) for s in order], range(4)).statistic
    assert tau >= 0.9, order
    assert sources.index[0] == "hidden_reference" and sources.index[-1] == "anchor"
    screening = {t.name: t.frame for t in result.analysis.tables}["post_screening"]
    excluded = set(screening.loc[screening["excluded"], "participant"])
    scores = table.groupby("participant")["score"]
    # Random raters (uniform scores) miss the reference in ~90 % of trials.
    random_raters = set(table.loc[table["stimulus_role"] == "reference"].groupby("participant")["score"]
                        .apply(lambda s: (s < 90).mean() > 0.5).loc[lambda x: x].index)
    assert random_raters and random_raters <= excluded
    assert len(excluded - random_raters) <= 0.05 * 200
    assert result.counts["participants"] == 200 - len(excluded)
    assert scores.ngroups == 200


@pytest.mark.parametrize("score, message", [(101, "whole numbers from 0 to 100"),
                                            (2.5, "whole numbers from 0 to 100")])
def test_a_table_with_bad_scores_is_refused(score, message):
    table = table_of(TRIALS).astype({"score": object})
    table.loc[0, "score"] = score
    with pytest.raises(AnalysisError, match=message):
        analyse(table, config(bootstrap=0))


def test_a_table_without_roles_is_analysed_without_screening():
    table = table_of(TRIALS).drop(columns="stimulus_role")
    result = analyse(table, config(bootstrap=0))
    assert "hidden_reference" not in result.analysis.sources.index
    assert any("no stimulus_role column" in note for note in result.notes)


def test_a_mushra_difference_rests_on_its_two_sources_clips():
    # The hidden reference and the anchor are sources of their own: 8 clips in 4 groups
    # (4 clip degrees of freedom), but a - b moves with a's and b's 4 clips only (2).
    table = simulate("mushra", {"a": 0.0, "b": 0.0}, participants=20, trials=6,
                     actions=("x",), clips_per_source=2, clip_sd=1.5, seed=5)
    result = analyse(table, config(bootstrap=40))
    differences = result.analysis.tests["differences"]
    assert differences["df"].tolist() == [2.0] * len(differences)
    assert any("a difference rests on as few as 2 degrees of freedom" in note
               for note in result.notes)
