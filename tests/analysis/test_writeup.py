"""The methods paragraph against what the study did, for every registered study type and
combination of its answer options, attention checks and repeats: it never names a
choice the participants did not have or a check that did not exist, counts in words,
rounds alpha and its interval alike, and says when participants were simulated."""

import itertools
import re

import pandas as pd
import pytest

from analysis.agreement import MIN_AGREEMENT_UNITS
from analysis.registry import get_analysis
from analysis.simulate import simulate, simulated_types
from analysis.study import analyse
from analysis.writeup import alpha_text
from tests.analysis.conftest import config

TYPES = simulated_types()
# Every type with every on/off setting of each of its answer options (and, for a table
# analysed without its study, the options unknown: None).
CASES = [(t, option, on) for t in TYPES
         for option in (list(get_analysis(t).answer_options) or [None])
         for on in ((True, False, None) if option else (None,))]
CHECKS = list(itertools.product((0, 1), (0, 1)))  # (catch trials, repeated trials)

TEMPLATED = [r"\(s\)", r"\b1 (participants|trials|judgements|comparisons|clips|units|sources)\b",
             r"more than 0\b", r"\d x the clip length", r"reported outcome", r": 0 participants"]
ALPHA = re.compile(r"alpha = (-?\d+\.(\d+)) \[(-?\d+\.(\d+)), (-?\d+\.(\d+))\]")


def paragraph(study_type, option=None, on=None, catch=0, repeats=0, **settings):
    plugin = get_analysis(study_type)
    # The option's answers are given only when it is on (or unknown): never when off.
    tie_rate = 0.25 if on in (True, None) and option else 0.0
    table = simulate(study_type, participants=14, trials=5, catch_trials=catch,
                     repeat_trials=repeats, tie_rate=tie_rate, seed=5, **settings)
    options = {} if on is None else {option: on}
    result = analyse(table, config(bootstrap=30, type_options=options))
    return result, result.methods(), plugin


@pytest.mark.parametrize("catch,repeats", CHECKS)
@pytest.mark.parametrize("study_type,option,on", CASES)
def test_the_paragraph_follows_the_options_checks_and_counts(study_type, option, on, catch,
                                                             repeats):
    result, text, plugin = paragraph(study_type, option, on, catch, repeats)
    lowered = text.lower()
    if option:
        spec = plugin.answer_options[option]
        used = any(re.search(rf"\b{re.escape(word)}", lowered) for word in spec.words)
        if on is False:
            assert not used, f"{option} off, yet: {text}"
        else:
            assert spec.design.strip(", ").lower() in lowered
    assert ("catch trial" in lowered) == bool(catch)
    assert ("a second time" in lowered) == bool(repeats)
    assert ("repeated trials do not enter" in lowered) == bool(repeats)
    for pattern in TEMPLATED:
        assert not re.search(pattern, text), (pattern, text)
    counts = result.counts
    assert (f"We analysed {counts['judgements']} judgements from {counts['participants']} "
            f"participants in {counts['trials']} trials") in text
    table = result.exclusions.set_index("rule")
    if table.iloc[1:-1]["judgements"].sum() == 0:
        assert "We excluded" not in text
    else:
        assert f"leaving {table.iloc[-1]['judgements']} of the {table.iloc[0]['judgements']}" in text
    found = ALPHA.search(text)
    if found:
        alpha, digits, low, low_digits, high, high_digits = found.groups()
        assert len(digits) == len(low_digits) == len(high_digits)
        assert float(low) <= float(alpha) <= float(high)
    assert text.startswith(f"These data are simulated: all {counts['participants']} analysed "
                           f"participants were bots")


@pytest.mark.parametrize("study_type", TYPES)
def test_fixed_clips_and_people_change_what_the_paragraph_says(study_type):
    table = simulate(study_type, participants=12, trials=4, seed=1).drop(columns="simulated")
    random = analyse(table, config(bootstrap=20)).methods()
    fixed = analyse(table, config(bootstrap=20, random_clips=False)).methods()
    assert "clips as random" in random and "clips were held fixed" in fixed
    assert "clips as random" not in fixed
    assert "mixed model" not in random.lower()  # fitted only when asked (--mixed-models)
    assert "simulated" not in random.lower() and "bot" not in random.split()


def test_outcomes_in_words_and_only_real_participants_demographics():
    table = simulate(TYPES[0], participants=12, trials=4, seed=3)
    bots = {1, 2}
    table["simulated"] = table["participant"].isin(bots)
    ids = sorted(table["participant"].unique())
    participants = pd.DataFrame({
        "participant": ids + [99, 100, 101],
        "outcome": ["completed"] * len(ids) + ["failed_attention", "no_consent", ""],
        "simulated": [p in bots for p in ids] + [False] * 3,
        "age_range": ["70+" if p in bots else "25-34" for p in ids] + [""] * 3,
        "comments": ["a free-text remark"] * (len(ids) + 3),
    })
    text = analyse(table, config(bootstrap=20), participants=participants).methods()
    assert text.startswith("2 of the 12 analysed participants were bots")
    assert (f"Of the {len(ids) + 3} participants who opened the study, {len(ids)} completed "
            f"the study, 1 was stopped after failing the attention checks, 1 did not consent "
            f"and 1 had not finished when the data were exported") in text
    assert "25-34: 10" in text and "70+" not in text and "free-text" not in text
    assert "outcome" not in text


def test_practice_and_planned_checks_come_from_the_study():
    table = simulate(TYPES[0], participants=12, trials=4, catch_trials=2, seed=3)
    text = analyse(table, config(bootstrap=20, study_options={
        "practice": True, "catch_trials": 2, "instructed_checks": 0})).methods()
    assert "2 catch trials per participant" in text
    assert "A practice trial came first; its answer is not analysed" in text
    assert "instructed" not in text
    assert "practice" not in analyse(table, config(bootstrap=20)).methods()


def test_alpha_and_its_interval_share_one_precision_and_an_outside_interval_is_named():
    inside = {"alpha": -0.005, "ci_low": -0.0204, "ci_high": 0.0113}
    assert alpha_text(inside) == "alpha = -0.01 [-0.02, 0.01]"
    outside = {"alpha": -0.005, "ci_low": -0.02, "ci_high": -0.01}  # the case
    text = alpha_text(outside)
    assert text.startswith("alpha = -0.01 (its bootstrap percentile interval, [-0.02, -0.01], "
                           "does not contain it")
    assert alpha_text({"alpha": 0.5, "ci_low": float("nan"), "ci_high": float("nan")}) == \
        "alpha = 0.50"


@pytest.mark.parametrize("study_type", TYPES)
def test_agreement_over_few_units_says_so(study_type):
    # One clip per source and one action: a handful of units, each judged by everyone.
    few = simulate(study_type, participants=6, trials=3, actions=("walk",), clips_per_source=1,
                   seed=4)
    result = analyse(few, config(bootstrap=20))
    text = result.methods()
    assert 0 < result.agreement["n_units"] < MIN_AGREEMENT_UNITS
    assert f"With fewer than {MIN_AGREEMENT_UNITS}" in text
    assert any("firm figure needs" in note for note in result.notes)
    many = analyse(simulate(study_type, participants=40, trials=6, clips_per_source=2, seed=4),
                   config(bootstrap=20))
    if many.agreement["n_units"] >= MIN_AGREEMENT_UNITS:
        assert f"With fewer than {MIN_AGREEMENT_UNITS}" not in many.methods()


@pytest.mark.parametrize("study_type", TYPES)
def test_instructed_checks_are_named_as_such(study_type):
    table = simulate(study_type, participants=12, trials=4, catch_trials=1, seed=6)
    checks = table["trial_kind"] == "catch"
    table["trial_kind"] = table["trial_kind"].astype(str).where(~checks, "instructed")
    table["is_catch"] = False  # an instructed check shows no broken clip
    text = analyse(table, config(bootstrap=20)).methods()
    assert "Attention was checked with 1 instructed check per participant" in text
    assert "catch trial" not in text.lower()
    assert "Instructed checks do not enter the statistics" in text


def test_the_paragraph_says_how_an_adaptive_study_chose_its_trials_and_stopped():
    from analysis.writeup import adaptive_sentences

    table = simulate(TYPES[0], participants=12, trials=4, seed=3)
    stopped = {"rule": "interval_width", "value": 0.6, "width": 0.574, "judgements": 1234,
               "certainty": 0.8, "interval": "clips", "target": "top_two"}
    text = analyse(table, config(bootstrap=20, study_options={
        "design": "adaptive", "adaptive": {"every": 50, "target": "top_two"},
        "stop_when": {"interval_width": 0.6}, "stopped": stopped})).methods()
    assert "The design was adaptive" in text and "every 50 answered main trials" in text
    assert "narrow most the intervals of the difference between the two sources estimated best" in text
    assert ("The study stopped by its stopping rule when the widest 95% interval of the "
            "difference between the two sources estimated best was 0.57, at most the rule's 0.6 "
            "(logit scale), after 1234 answered main trials") in text
    assert "adaptive" not in analyse(table, config(bootstrap=20)).methods()
    assert "batches" not in text  # none asked for (analyze passes the settings that ran)
    batched = adaptive_sentences({"design": "adaptive", "adaptive": {"every": 50, "batch": 50}})
    assert batched[1] == ("The pairs of sources were planned in batches of 50 comparisons, each "
                          "pair chosen after the posterior had been updated by the pairs chosen "
                          "before it in the batch")
    budget = adaptive_sentences({"stop_when": {"judgements": 500},
                                 "stopped": {"rule": "judgements", "value": 500, "judgements": 512,
                                             "width": 1.0, "certainty": 0.5}})
    assert budget == ["The study stopped by its stopping rule when its budget of 500 answered main "
                      "trials was reached (512 answered main trials); the rule was checked in the "
                      "background every few answers, its places were closed then, and the answers "
                      "of those still taking part were kept"]
    running = adaptive_sentences({"stop_when": {"rank_certainty": 0.95}})
    assert running == ["The study had a stopping rule (rank certainty 0.95) that had not been met "
                       "when the data were exported"]
