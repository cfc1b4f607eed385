"""Exclusion rules applied, counted and reported; switched off and tuned."""

import pytest

from analysis.study import analyse
from tests.analysis.conftest import config, make_table, trial

RANKS = [("real", 1), ("a2m", 2), ("gru", 3)]


def study_table():
    """Four participants with two main trials each (3 clips of 2 s) and a catch trial.

    p2 fails its catch trial; p3 answers one trial in 1.5 s; p4 answers one trial in
    3 s that holds a 3.5 s clip.
    """
    trials = []
    for participant in (1, 2, 3, 4):
        trials.append(trial(participant, RANKS, action="eat"))
        second = trial(participant, RANKS, action="walk")
        if participant == 3:
            second["time_ms"] = 1500
        trials.append(second)
        trials.append(trial(participant, [("catch", 1), ("real", 2), ("a2m", 3)], kind="catch",
                            catch_passed=participant != 2))
    table = make_table("ranking", trials)
    slow_clip = (table["participant"] == 4) & (table["action"] == "walk") & (table["source"] == "gru")
    table.loc[slow_clip, "duration"] = 3.5
    table.loc[(table["participant"] == 4) & (table["action"] == "walk"), "time_ms"] = 3000
    return table


def counts(result):
    return {row["rule"]: (row["participants"], row["trials"], row["judgements"])
            for row in result.exclusions.to_dict("records")}


def test_rules_are_applied_and_counted():
    result = analyse(study_table(), config())
    assert counts(result) == {
        "Main-trial judgements before exclusions": (4, 8, 24),
        "Failed an attention check": (1, 2, 6),
        "Answered a repeated trial differently": (0, 0, 0),
        "Answered before the longest clip of the trial could have played once": (2, 2, 6),
        "Analysed": (3, 4, 12),
    }
    assert result.counts["judgements"] == 12 and result.counts["participants"] == 3
    quality = result.quality.set_index("check")
    assert quality.loc["catch trials passed", "value"] == pytest.approx(3 / 4)
    text = result.methods()
    assert "We excluded 1 participant who failed an attention check (6 judgements) and 2 " \
           "trials answered before the longest clip of the trial could have played once " \
           "(2 participants, 6 judgements), leaving 12 of the 24 main-trial judgements" in text
    assert "(s)" not in text and "1 participants" not in text


def test_no_exclusions_keeps_everything_but_still_counts():
    result = analyse(study_table(), config(exclusions=False))
    table = counts(result)
    assert table["Analysed"] == (4, 8, 24)
    assert table["Failed an attention check"] == (1, 2, 6)
    assert result.exclusions.set_index("rule").loc["Analysed", "judgements"] == 24
    assert "No exclusions were applied" in result.methods()


def test_time_factor_and_catch_tolerance_are_configurable():
    lenient = analyse(study_table(), config(min_time_factor=0.5, max_failed_catch=1))
    table = counts(lenient)
    assert table["Answered in less than 0.5 times the length of the trial's longest clip"] == (0, 0, 0)
    assert table["Failed more than one attention check"] == (0, 0, 0)
    assert table["Analysed"] == (4, 8, 24)


def test_speed_rule_is_skipped_without_durations():
    result = analyse(study_table().drop(columns=["duration"]), config())
    rows = result.exclusions.set_index("rule")
    assert rows.loc["Answered before the longest clip of the trial could have played once", "applied"] == "skipped (no data)"
    assert rows.loc["Analysed", "judgements"] == 18
    assert any("no clip durations" in note for note in result.notes)
    assert "could not be applied" in result.methods()


def test_completed_only_is_a_counted_rule():
    table = study_table()
    table.loc[table["participant"] == 1, "completed"] = False
    table["completed"] = table["completed"].astype(bool)
    result = analyse(table, config(completed_only=True))
    assert counts(result)["Did not complete the study"] == (1, 2, 6)
    assert counts(result)["Analysed"] == (2, 2, 6)  # p3 and p4 keep one trial each


def test_repeated_trials_are_compared_with_the_first_answer():
    clips = [("real", True, "r1"), ("a2m", False, "g1"), ("gru", False, "g2")]
    flipped = [("real", True, "r1"), ("a2m", True, "g1"), ("gru", False, "g2")]
    trials = [trial(1, clips), trial(2, clips), trial(1, clips, kind="repeat"),
              trial(2, flipped, kind="repeat")]
    result = analyse(make_table("fake_or_real", trials), config())
    repeat = result.quality.set_index("check").loc["repeated judgements identical"]
    assert repeat["value"] == pytest.approx(5 / 6) and repeat["n"] == 6
    assert result.counts["judgements"] == 6  # repeats stay out of the statistics


def test_repeats_match_their_participant_after_exclusions():
    clips = [("real", True, "r1"), ("a2m", False, "g1")]
    trials = [trial(1, clips, time_ms=10), trial(2, clips), trial(3, clips),
              trial(2, clips, kind="repeat"), trial(3, [("real", False, "r1"), ("a2m", True, "g1")],
                                                    kind="repeat")]
    result = analyse(make_table("fake_or_real", trials), config())
    repeat = result.quality.set_index("check").loc["repeated judgements identical"]
    assert repeat["value"] == pytest.approx(0.5) and repeat["participants"] == 2


def test_changed_repeats_are_counted_and_excluded_only_when_asked():
    trials = []
    for participant in (1, 2, 3):
        trials.append(trial(participant, RANKS, action="eat"))
        trials.append(trial(participant, RANKS, action="walk"))
        trials.append(trial(participant, RANKS, action="eat", kind="repeat",
                            catch_passed=participant != 3))
    table = make_table("ranking", trials)
    rule = "Answered a repeated trial differently"
    default = analyse(table, config())
    rows = default.exclusions.set_index("rule")
    assert counts(default)[rule] == (1, 2, 6)  # p3's main judgements
    assert rows.loc[rule, "applied"].startswith("no (counted only")
    assert counts(default)["Analysed"] == (3, 6, 18)
    assert "1 participant answered a repeated trial differently (reported, " \
           "not excluded)" in default.methods()
    strict = analyse(table, config(max_failed_repeats=0))
    assert counts(strict)[rule] == (1, 2, 6) and counts(strict)["Analysed"] == (2, 4, 12)
    assert counts(analyse(table, config(max_failed_repeats=1)))["Analysed"] == (3, 6, 18)


def test_a_table_without_trial_kinds_still_excludes_failed_catch_trials():
    result = analyse(study_table().drop(columns=["trial_kind"]), config())
    assert counts(result)["Failed an attention check"][0] == 1
