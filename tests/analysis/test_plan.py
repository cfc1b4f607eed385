"""The study planner: power over participants x clips, from assumptions or a pilot, and cost."""

import math

import numpy as np
import pytest

from analysis import plan, simulate
from analysis.study import analyse
from tests.analysis.conftest import config


def test_simulated_power_grows_with_participants_and_clips():
    assumptions = plan.Assumptions("rating_standards", effect=1.0, clip_sd=0.5, trials=6)
    frame = plan.simulated_power(assumptions, participants=(8, 40), clips=(2, 8), studies=6,
                                 bootstrap=40)
    power = frame.set_index(["participants", "clips"])["power"]
    width = frame.set_index(["participants", "clips"])["width"]
    assert power[(40, 8)] >= power[(8, 2)]
    assert width[(40, 8)] < width[(8, 2)]
    assert frame["power_low"].le(frame["power"]).all() and frame["power_high"].ge(frame["power"]).all()


def test_pilot_plan_scales_the_variance_shares_and_holds_in_simulation():
    pilot = analyse(simulate.simulate("rating_standards", {"a": 0.8, "b": 0.0}, participants=30,
                                      trials=6, actions=("x",), clips_per_source=4, clip_sd=0.5,
                                      seed=3), config(bootstrap=150))
    components = plan.pilot_components(pilot, "a", "b")
    assert components["participants"] == 30 and components["clips"] == 4
    predicted = plan.pilot_power(components, participants=(30, 60), clips=(4, 8), effect=0.6)
    se = predicted.set_index(["participants", "clips"])["se"]
    # The pilot's own design gives back its own standard error.
    assert se[(30, 4)] == pytest.approx(components["se"])
    assert se[(60, 8)] < se[(30, 4)]
    # Doubling clips removes half the clips' part of the variance, no more.
    shares = components["share_clips"]
    assert se[(30, 8)] ** 2 == pytest.approx(components["se"] ** 2 * (1 - shares / 2))
    # The recommendation's power is met by studies of that design (within the noise of 16).
    best = plan.recommend(predicted, target=0.5)
    found = []
    for seed in range(16):
        table = simulate.simulate("rating_standards", {"a": 0.8, "b": 0.0},
                                  participants=int(best["participants"]), trials=6, actions=("x",),
                                  clips_per_source=int(best["clips"]), clip_sd=0.5, seed=100 + seed)
        row = analyse(table, config(bootstrap=60, seed=seed)).analysis.tests["differences"].iloc[0]
        found.append(row["p"] < 0.05)
    assert abs(np.mean(found) - best["power"]) < 0.35


def test_minutes_costs_and_the_recommendation():
    minutes = plan.minutes_per_participant(trials=12, clip_seconds=4.0)
    assert minutes == pytest.approx(plan.OVERHEAD_MINUTES + 12 * (4.0 + plan.ANSWER_SECONDS) / 60)
    frame = plan.pilot_power({"difference": 0.3, "se": 0.2, "share_participants": 0.3,
                              "share_clips": 0.6, "share_residual": 0.1, "participants": 20,
                              "clips": 2, "trials": 12}, participants=(20, 40, 80), clips=(2, 8))
    costed = plan.costs(frame, minutes, reward_per_hour=12.0)
    reward = math.ceil(minutes * 12.0 * 100 / 60) / 100
    assert costed["reward"].iloc[0] == pytest.approx(reward)
    assert costed["cost"].tolist() == pytest.approx(
        (costed["participants"] * reward * (1 + plan.PROLIFIC_SERVICE_FEE)).tolist())
    best = plan.recommend(costed, target=0.6)
    assert best["reached"] and best["clips"] == 8  # clips dominate: more clips, few people
    # Two clips leave the difference 2 degrees of freedom: the t quantile the analysis
    # will use, not the normal one, sets the width and the power.
    two = costed.loc[costed["clips"] == 2]
    assert (two["df"] == 2).all() and (two["power"] < 0.1).all()
    none = plan.recommend(costed, target=0.9999)
    assert not none["reached"]
    assert "more clips gain the most" in plan.advice(none, 0.9999, costed)
    figure = plan.power_figure(costed)
    assert len(figure.axes[0].lines) == 3  # two designs of clips and the target


def test_session_minutes_come_from_the_planned_session_and_say_so():
    trials = [("practice", 20.0), ("main", 30.0), ("main", 40.0), ("catch", 10.0)]
    own = plan.session_minutes(60.0, trials, study="study x")
    assert own.minutes == pytest.approx((60 + 20 + 70 + 10) / 60)
    assert own.source.startswith("estimated by study x's duration model: 2 main trials of 35.0 s")
    rescaled = plan.session_minutes(60.0, trials, main_trials=10, study="study x")
    assert rescaled.minutes == pytest.approx((60 + 30 + 10 * 35) / 60)
    assert "rescaled from its 2 to 10 main trials" in rescaled.source
    measured = plan.session_minutes(60.0, trials, measured_seconds=420.0, n_measured=6)
    assert measured.minutes == 7.0 and measured.source.startswith("measured: the median session of 6")
    assert plan.session_minutes(60.0, [("practice", 20.0)]) is None
    assumed = plan.assumed_minutes(12, 4.0)
    assert assumed.minutes == plan.minutes_per_participant(12, 4.0)
    assert assumed.source.startswith("assumed: 12 trials of 4 s clips")


def test_the_recommendation_is_confirmed_on_fresh_studies():
    """The grid's estimate of the design it picks is biased upward by the picking; the
    stated power comes from studies drawn after the pick."""
    assumptions = plan.Assumptions("rating_standards", effect=1.0, clip_sd=0.3, trials=6)
    grid = plan.simulated_power(assumptions, participants=(8, 30), clips=(2, 6), studies=6,
                                bootstrap=20)
    best = plan.recommend(grid, target=0.5)
    confirmed = plan.confirm(assumptions, best, studies=6, bootstrap=20, target=0.5)
    assert confirmed["grid_power"] == best["power"] and confirmed["confirmed"] == 6
    assert (confirmed["participants"], confirmed["clips"]) == (best["participants"], best["clips"])
    assert confirmed["reached"] == (confirmed["power"] >= 0.5)
    assert confirmed["power_low"] <= confirmed["power"] <= confirmed["power_high"]
    said = plan.advice(confirmed, 0.5, grid)
    assert "fresh simulated studies" in said and f"{confirmed['grid_power']:.0%}" in said
