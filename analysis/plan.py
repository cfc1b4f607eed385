"""Plan a study before paying for it: power and interval width over participants x clips.

Two ways in, both through the analysis a study's answers will get:

- from assumptions (:class:`Assumptions`: a study type, the strength difference of two
  sources on the logit scale, how much clips of one source vary, the answers' noise),
  :func:`simulated_power` simulates whole studies (:func:`analysis.simulate.simulate`)
  for every design of a grid of participants and clips per source and condition, analyses
  each with :func:`analysis.study.analyse` (participants and clips random), and counts
  how often the difference of the two sources is significant, and how wide its interval is;
- from a pilot (its :class:`~analysis.study.StudyResult`), :func:`pilot_power` takes the
  pilot's difference, its standard error and the shares of its variance from
  participants, clips and single answers, and scales each share by how the design
  changes it (participants' and single answers' parts by ``P0 / P`` at the same trials per
  participant, the clips' part by ``m0 / m``).

:func:`costs` adds minutes per participant and the Prolific cost; :func:`recommend`
picks the cheapest design that reaches the target power, and with assumptions
:func:`confirm` measures its power again on fresh studies (the pick's own estimate is
biased upward by the picking). The minutes come from an
existing study's duration model (:func:`session_minutes`, given the seconds of its
planned session: the survey app's ``duration.session_seconds``), or without a study from
assumptions (:func:`assumed_minutes`); either says where its number came from.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from analysis.simulate import simulate
from analysis.stats import wilson_interval
from analysis.study import AnalysisConfig, analyse
from analysis.tables import AnalysisError

# Prolific's service fee on rewards (and bonuses) for academic workspaces when written:
# 33.3 %, VAT added where it applies. Other workspaces pay other rates: pass yours.
PROLIFIC_SERVICE_FEE = 0.333
# What a participant does besides the trials: consent, instructions, practice, questions.
OVERHEAD_MINUTES = 3.0
ANSWER_SECONDS = 8.0


@dataclass
class Assumptions:
    """What a planned study is assumed to be: source ``a`` stronger than ``b`` by
    ``effect`` (logit scale), clips of a source varying with SD ``clip_sd`` about it,
    answers with ``noise``, ``trials`` main trials per participant over ``conditions``
    actions or prompts, ``clips_per_trial`` for the types that choose it."""

    study_type: str
    effect: float = 0.5
    clip_sd: float = 0.5
    noise: float = 1.0
    trials: int = 10
    conditions: int = 1
    clips_per_trial: int = 2


def _difference(result) -> dict:
    table = result.analysis.tests["differences"]
    rows = table.loc[table["a"].isin(["a", "b"]) & table["b"].isin(["a", "b"])]
    if rows.empty:
        raise AnalysisError("the analysis has no difference of sources a and b")
    row = rows.iloc[0]
    return {"p": float(row["p"]), "width": float(row["ci_high"] - row["ci_low"])}


def simulated_power(assumptions: Assumptions, participants=(20, 40, 80), clips=(2, 4, 8),
                    studies: int = 50, bootstrap: int = 100, alpha: float = 0.05,
                    seed: int = 0) -> pd.DataFrame:
    """Return per design (``participants``, ``clips`` per source and condition) the
    ``power`` (share of ``studies`` simulated studies with p < ``alpha`` for a - b), its
    Wilson interval, and the mean interval ``width``."""
    records = []
    actions = tuple(f"condition_{i + 1}" for i in range(assumptions.conditions))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for n_participants in participants:
            for n_clips in clips:
                found = []
                for r in range(studies):
                    table = simulate(assumptions.study_type, {"a": assumptions.effect, "b": 0.0},
                                     participants=n_participants, trials=assumptions.trials,
                                     actions=actions, clips_per_source=n_clips,
                                     clip_sd=assumptions.clip_sd, noise=assumptions.noise,
                                     clips_per_trial=assumptions.clips_per_trial,
                                     seed=seed + 7919 * r)
                    found.append(_difference(analyse(table, AnalysisConfig(bootstrap=bootstrap,
                                                                           seed=seed + r))))
                significant = int(sum(f["p"] < alpha for f in found))
                low, high = wilson_interval(significant, studies)
                records.append({"participants": n_participants, "clips": n_clips,
                                "power": significant / studies, "power_low": float(low),
                                "power_high": float(high),
                                "width": float(np.mean([f["width"] for f in found])),
                                "studies": studies})
    return pd.DataFrame(records)


def pilot_components(result, a: str, b: str) -> dict:
    """Return the pilot's difference ``a - b``, its standard error, the variance shares
    and the design it was measured on (participants, clips per source and condition,
    trials per participant)."""
    table = result.analysis.tests.get("differences")
    if table is None:
        raise AnalysisError(f"the pilot's {result.study_type} analysis has no differences to plan from")
    sign = 1.0
    row = table.loc[(table["a"] == a) & (table["b"] == b)]
    if row.empty:
        row, sign = table.loc[(table["a"] == b) & (table["b"] == a)], -1.0
    if row.empty:
        known = sorted(set(table["a"]) | set(table["b"]))
        raise AnalysisError(f"the pilot has no sources {a!r} and {b!r}; it has {', '.join(known)}")
    row = row.iloc[0]
    clips = result.analysis.tables
    per = next((t.frame for t in clips if t.name == "clips"), None)
    m0 = float(per.loc[[a, b], "fewest_per_condition"].mean()) if per is not None else float("nan")
    # Conditions a source's clips come in (its clips over the fewest per condition).
    conditions = (float((per.loc[[a, b], "n_clips"] / per.loc[[a, b], "fewest_per_condition"]).mean())
                  if per is not None else 1.0)
    return {"difference": sign * float(row["difference"]), "se": float(row["se"]),
            "share_participants": float(row["share_participants"]),
            "share_clips": float(row["share_clips"]), "share_residual": float(row["share_residual"]),
            "participants": int(result.counts["participants"]), "clips": m0,
            "conditions": conditions,
            "trials": result.counts["trials"] / max(result.counts["participants"], 1)}


def pilot_power(components: dict, participants=(20, 40, 80), clips=(2, 4, 8),
                effect: float | None = None, alpha: float = 0.05) -> pd.DataFrame:
    """Return per design the expected standard error, degrees of freedom, interval
    ``width`` and ``power`` of the difference (the pilot's own, or ``effect`` on its
    scale), scaling the pilot's variance shares (same trials per participant).

    The width and the power use the t quantile the analysis will use for that design:
    the fewer of ``P - 1`` and the two sources' clips' degrees of freedom (``m - 1`` per
    source and condition, as :meth:`analysis.crossed.Crossed.clip_df` counts them; only
    ``P - 1`` where the pilot's clips show no variance), so that a design of few clips is
    not promised the normal quantile's narrower interval; power by the shifted t."""
    effect = components["difference"] if effect is None else effect
    variance = components["se"] ** 2
    conditions = components.get("conditions", 1.0)
    records = []
    for n_participants in participants:
        for n_clips in clips:
            scale_p = components["participants"] / n_participants
            part = variance * ((components["share_participants"] + components["share_residual"])
                               * scale_p + components["share_clips"] * components["clips"] / n_clips)
            se = math.sqrt(part)
            df = float(max(n_participants - 1, 1))
            if components["share_clips"] > 0:
                df = min(df, max(2 * conditions * (n_clips - 1), 1.0))
            quantile = scipy_stats.t.ppf(1 - alpha / 2, df)
            shift = abs(effect) / se if se > 0 else math.inf
            power = scipy_stats.t.sf(quantile - shift, df) + scipy_stats.t.cdf(-quantile - shift, df)
            records.append({"participants": n_participants, "clips": n_clips, "power": float(power),
                            "width": 2 * quantile * se, "se": se, "df": df})
    return pd.DataFrame(records)


def minutes_per_participant(trials: int, clip_seconds: float, plays: float = 1.0,
                            answer_seconds: float = ANSWER_SECONDS,
                            overhead_minutes: float = OVERHEAD_MINUTES) -> float:
    """Return the expected minutes of one participant: each trial's clips played ``plays``
    times (the server waits for them) and answered, plus the pages around the trials."""
    return overhead_minutes + trials * (clip_seconds * plays + answer_seconds) / 60


@dataclass(frozen=True)
class Minutes:
    """Minutes per participant and where they came from, in words."""

    minutes: float
    source: str


def assumed_minutes(trials: int, clip_seconds: float) -> Minutes:
    """Return :func:`minutes_per_participant` of assumed trials and clip length."""
    return Minutes(minutes_per_participant(trials, clip_seconds),
                   f"assumed: {trials} trials of {clip_seconds:g} s clips played once and "
                   f"{ANSWER_SECONDS:g} s to answer, plus {OVERHEAD_MINUTES:g} minutes of other "
                   f"pages")


def session_minutes(fixed_seconds: float, trials: list[tuple[str, float]], main_trials=None,
                    measured_seconds: float | None = None, n_measured: int = 0,
                    study: str = "the study", main_kind: str = "main") -> Minutes | None:
    """Return the minutes of a study's session from its duration model, or None when it
    plans no main trial (nothing built yet).

    ``fixed_seconds`` are the pages around the trials, ``trials`` each planned trial's
    kind and seconds (its required clips played once, the type's answer time, reading);
    ``measured_seconds`` the median of completed sessions when there are enough
    (``n_measured``). With ``main_trials`` other than the study's own number of main
    trials, the estimate is rescaled: the same pages and extra trials, and that many
    main trials of the study's mean main-trial seconds (the measured median holds for
    the study's own number only)."""
    main = [seconds for kind, seconds in trials if kind == main_kind]
    if not main:
        return None
    other = sum(seconds for kind, seconds in trials if kind != main_kind)
    per_trial = sum(main) / len(main)
    parts = (f"{len(main)} main trials of {per_trial:.1f} s on average (their required clips "
             f"played once, the type's answer time and reading)"
             + (f", {len(trials) - len(main)} other trials ({other:.0f} s)" if other else "")
             + f" and {fixed_seconds:.0f} s of other pages")
    if main_trials is None or main_trials == len(main):
        estimate = fixed_seconds + other + sum(main)
        if measured_seconds is not None:
            return Minutes(measured_seconds / 60,
                           f"measured: the median session of {n_measured} completed participants "
                           f"of {study} (its duration model's estimate was "
                           f"{estimate / 60:.1f} minutes: {parts})")
        return Minutes(estimate / 60, f"estimated by {study}'s duration model: {parts}")
    estimate = fixed_seconds + other + main_trials * per_trial
    return Minutes(estimate / 60,
                   f"estimated by {study}'s duration model, rescaled from its {len(main)} to "
                   f"{main_trials} main trials of {per_trial:.1f} s on average (required clips "
                   f"played once, the type's answer time and reading)"
                   + (f", {len(trials) - len(main)} other trials ({other:.0f} s)" if other else "")
                   + f" and {fixed_seconds:.0f} s of other pages")


def costs(frame: pd.DataFrame, minutes: float, reward_per_hour: float,
          service_fee: float = PROLIFIC_SERVICE_FEE) -> pd.DataFrame:
    """Return ``frame`` with ``minutes``, the ``reward`` per participant (rounded up to the
    cent, as Prolific's draft does) and the ``cost`` with the service fee."""
    reward = math.ceil(minutes * reward_per_hour * 100 / 60) / 100
    out = frame.copy()
    out["minutes"] = round(minutes, 1)
    out["reward"] = reward
    out["cost"] = out["participants"] * reward * (1 + service_fee)
    return out


def recommend(frame: pd.DataFrame, target: float = 0.8) -> dict:
    """Return the cheapest design reaching ``target`` power (fewest participants, then
    fewest clips), or the most powerful one with ``reached`` False."""
    reached = frame.loc[frame["power"] >= target]
    if len(reached):
        order = ["cost", "clips"] if "cost" in frame.columns else ["participants", "clips"]
        best = reached.sort_values(order, kind="stable").iloc[0]
        return {"reached": True, **best.to_dict()}
    best = frame.sort_values(["power"], ascending=False, kind="stable").iloc[0]
    return {"reached": False, **best.to_dict()}


# Seeds of the confirming studies start here (the grid's are ``seed + 7919 r``).
CONFIRM_SEED = 1_000_000_007


def confirm(assumptions: Assumptions, recommendation: dict, studies: int = 50,
            bootstrap: int = 100, alpha: float = 0.05, seed: int = 0,
            target: float = 0.8) -> dict:
    """Return ``recommendation`` with its power measured again on ``studies`` fresh
    simulated studies of its design (seeds the grid did not draw), and whether that
    reaches ``target``; the grid's estimate is kept as ``grid_power``.

    The grid's estimate of the design it picks is biased upward: of designs near the
    target, the one whose estimate came out high is picked. Studies drawn after the pick
    are not, so they give the power the recommendation states."""
    fresh = simulated_power(assumptions, (int(recommendation["participants"]),),
                            (int(recommendation["clips"]),), studies, bootstrap, alpha,
                            seed + CONFIRM_SEED).iloc[0]
    out = dict(recommendation)
    out.update(grid_power=float(recommendation["power"]), power=float(fresh["power"]),
               power_low=float(fresh["power_low"]), power_high=float(fresh["power_high"]),
               width=float(fresh["width"]), confirmed=int(studies),
               reached=bool(fresh["power"] >= target))
    return out


def advice(recommendation: dict, target: float, frame: pd.DataFrame) -> str:
    """Return the recommendation in words."""
    r = recommendation
    cost = f", {r['minutes']:.0f} minutes each, cost {r['cost']:.2f}" if "cost" in r else ""
    again = (f" on {r['confirmed']} fresh simulated studies (the grid's estimate "
             f"{r['grid_power']:.0%})" if "confirmed" in r else "")
    if r["reached"]:
        return (f"{int(r['participants'])} participants and {int(r['clips'])} clips per source and "
                f"condition reach {r['power']:.0%} power{again} (target {target:.0%}){cost}")
    if r.get("grid_power", 0.0) >= target:
        return (f"the cheapest design estimated to reach {target:.0%} power, "
                f"{int(r['participants'])} participants and {int(r['clips'])} clips, reaches "
                f"{r['power']:.0%}{again}{cost}: take a larger design, or plan again with "
                f"more --studies")
    more_clips = frame.groupby("clips")["power"].max()
    more_people = frame.groupby("participants")["power"].max()
    gain_clips = more_clips.iloc[-1] - more_clips.iloc[0]
    gain_people = more_people.iloc[-1] - more_people.iloc[0]
    what = "clips" if gain_clips > gain_people else "participants"
    return (f"no design of the grid reaches {target:.0%} power; the best, {int(r['participants'])} "
            f"participants and {int(r['clips'])} clips, reaches {r['power']:.0%}{again}{cost}; "
            f"more {what} gain the most")


def power_figure(frame: pd.DataFrame, target: float = 0.8):
    """Return a matplotlib figure: power against participants, one line per clips."""
    # Imported here, as analysis.figures does: planning a table needs no matplotlib.
    from matplotlib.figure import Figure

    figure = Figure(figsize=(6, 4))
    axes = figure.subplots()
    for clips, group in frame.groupby("clips"):
        axes.plot(group["participants"], group["power"], marker="o", label=f"{clips} clips")
    axes.axhline(target, color="grey", linestyle="--", linewidth=1)
    axes.set_xlabel("participants")
    axes.set_ylabel("power")
    axes.set_ylim(0, 1)
    axes.legend(title="per source and condition")
    figure.tight_layout()
    return figure
