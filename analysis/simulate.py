"""Simulated response tables: raters with known source strengths, for every study type.

Each source has a Bradley-Terry strength (log scale); a clip's quality is its source's
strength plus a small clip effect. Attentive raters answer from the quality with noise:

- ranking: ranks by quality + Gumbel noise (a Plackett-Luce draw);
- pairwise: left wins with probability sigmoid((q_left - q_right + position_bias) / noise),
  with ``tie_rate`` of comparisons called both good (mean quality above the middle) or
  both bad;
- pairwise_graded: the left clip's grade cuts ``q_left - q_right + position_bias + noise *
  logistic`` at +-0.5, +-1.5, +-2.5 into the 7-point scale (a cumulative-logit draw);
  ``tie_rate`` of comparisons whose mean quality is below the middle are called both bad;
- fake_or_real: judged real with probability sigmoid((q - middle) / noise + rater bias);
- ratings: quality + rater bias + logistic noise, cut into 1..5 at thresholds spread
  evenly over the strengths;
- mushra: one clip per source plus a hidden reference (strength above the best source's)
  and a low anchor (below the worst's), in random places, each scored 0-100 as
  ``100 sigmoid(quality + rater bias + logistic noise - middle)``; an attentive rater
  scores the hidden reference 90-100 but in ``MUSHRA_SLIPS`` of trials;
- best_of_k: ``clips_per_trial`` clips of distinct sources (at most one per source), the
  best by quality + Gumbel noise picked (a Plackett-Luce top-1 draw), with ``tie_rate``
  of trials answered all good (mean quality above the middle) or all bad.

Inattentive raters answer at random and fail every catch trial; speeders answer faster
than the clips last. The table has the columns of :mod:`analysis.tables`, so the real
analysis runs on it. Everything is vectorised: a million judgements take about a second.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.tables import RESPONSE_COLUMNS, AnalysisError

# The answers of a graded pairwise trial, best for the left clip first (see
# analysis.pairwise_graded).
GRADED_CHOICES = ("left_much", "left", "left_slightly", "no_preference", "right_slightly",
                  "right", "right_much", "both_bad")
STRENGTHS = {"real": 4.0, "a2m": 3.0, "cond_gru": 1.0}
ACTIONS = ("walk", "eat", "jump", "sit")
STUDY_TYPES = ("ranking", "fake_or_real", "rating_standards", "rating_reference", "pairwise",
               "pairwise_graded", "best_of_k", "mushra")
# Answer columns of a type beyond analysis.tables.RESPONSE_COLUMNS (as the export adds them).
EXTRA_COLUMNS = {"best_of_k": ("pick",), "mushra": ("stimulus_role", "score")}
MUSHRA_SLIPS = 0.02


def simulate(study_type: str, strengths: dict | None = None, participants: int = 200,
             trials: int = 10, *, actions=ACTIONS, clips_per_source: int = 5,
             clips_per_trial: int = 6, noise: float = 1.0, clip_sd: float = 0.3,
             inattentive: float = 0.0, speeders: float = 0.0, catch_trials: int = 0,
             repeat_trials: int = 0, position_bias: float = 0.0, tie_rate: float = 0.1,
             duration: float = 2.0, seed: int = 0, study: str = "simulated") -> pd.DataFrame:
    """Return a response table of ``participants`` x ``trials`` main trials of ``study_type``.

    ``strengths`` maps source to log-strength (default :data:`STRENGTHS`);
    ``clips_per_trial`` applies to fake_or_real (ranking and rating_standards show one
    clip per source, rating_reference one clip, pairwise two). ``inattentive`` and
    ``speeders`` are the shares of such raters; each rater also gets ``catch_trials``
    catch trials and ``repeat_trials`` repeats of their first main trials.
    """
    if study_type not in STUDY_TYPES:
        raise AnalysisError(f"cannot simulate {study_type!r}; choose from {', '.join(STUDY_TYPES)}")
    strengths = dict(STRENGTHS if strengths is None else strengths)
    if participants < 1 or trials < 1 or len(strengths) < 1:
        raise AnalysisError("simulate at least one participant, one trial and one source")
    rng = np.random.default_rng(seed)
    names = np.array(list(strengths), dtype=object)
    strength = np.array(list(strengths.values()), dtype=float)
    centre = (strength.min() + strength.max()) / 2
    if study_type == "mushra":  # the hidden reference and the low anchor, as two more sources
        names = np.append(names, ["reference", "anchor"])
        strength = np.append(strength, [strength.max() + 1.0, strength.min() - 2.0])
    actions = np.asarray(actions, dtype=object)
    n_sources = len(names)

    # Trials: main, then catch, then repeats of the first main trials, per participant.
    per_participant = trials + catch_trials
    n_trials = participants * per_participant
    trial_participant = np.repeat(np.arange(participants), per_participant)
    trial_index = np.tile(np.arange(per_participant), participants)
    trial_action = rng.integers(0, len(actions), n_trials)
    sources = _trial_sources(study_type, rng, n_trials, n_sources, clips_per_trial)
    m = sources.shape[1]
    row_trial = np.repeat(np.arange(n_trials), m)
    row_source = sources.ravel()
    clip = rng.integers(0, clips_per_source, len(row_trial))
    stimulus = (trial_action[row_trial] * n_sources + row_source) * clips_per_source + clip
    position = np.argsort(rng.random((n_trials, m)), axis=1).ravel()
    kind = np.where(trial_index[row_trial] < trials, "main", "catch").astype(object)
    if repeat_trials:
        chosen = np.flatnonzero(trial_index < min(repeat_trials, trials))
        copied = (chosen[:, None] * m + np.arange(m)).ravel()
        row_trial = np.concatenate([row_trial, n_trials + np.repeat(np.arange(len(chosen)), m)])
        row_source = np.concatenate([row_source, row_source[copied]])
        stimulus = np.concatenate([stimulus, stimulus[copied]])
        position = np.concatenate([position, position[copied]])
        kind = np.concatenate([kind, np.full(len(copied), "repeat", dtype=object)])
        trial_participant = np.concatenate([trial_participant, trial_participant[chosen]])
        trial_index = np.concatenate([trial_index, per_participant + trial_index[chosen]])
        trial_action = np.concatenate([trial_action, trial_action[chosen]])
    participant = trial_participant[row_trial]
    n_rows = len(row_trial)

    careless = rng.random(participants) < inattentive
    fast = rng.random(participants) < speeders
    n_stimuli = len(actions) * n_sources * clips_per_source
    quality = strength[row_source] + rng.normal(0.0, clip_sd, n_stimuli)[stimulus]
    random = careless[participant]
    table = {"rank": _missing(n_rows, np.int64), "rating": _missing(n_rows, np.int64),
             "judged_real": _missing(n_rows, bool),
             "choice": pd.Categorical.from_codes(np.full(n_rows, -1),
                                                 ["left", "right", "both_good", "both_bad"])}
    middle = (strength.min() + strength.max()) / 2
    if study_type == "ranking":
        utility = np.where(random, 0.0, quality) + noise * rng.gumbel(size=n_rows)
        utility = utility.reshape(-1, m)
        ranks = np.empty_like(utility, dtype=np.int64)
        np.put_along_axis(ranks, np.argsort(-utility, axis=1), np.arange(1, m + 1)[None], axis=1)
        table["rank"] = pd.array(ranks.ravel(), dtype="Int64")
    elif study_type == "fake_or_real":
        bias = rng.normal(0.0, 0.3, participants)[participant]
        chance = np.where(random, 0.5, _sigmoid((quality - middle) / noise + bias))
        table["judged_real"] = pd.array(rng.random(n_rows) < chance, dtype="boolean")
    elif study_type.startswith("rating"):
        latent = quality + rng.normal(0.0, 0.3, participants)[participant] + noise * rng.logistic(size=n_rows)
        cuts = np.linspace(strength.min() - 0.5, strength.max() + 0.5, 6)[1:-1]
        ratings = np.where(random, rng.integers(1, 6, n_rows), 1 + np.searchsorted(cuts, latent))
        table["rating"] = pd.array(ratings, dtype="Int64")
    elif study_type == "pairwise_graded":
        table["choice"] = pd.Categorical(
            _graded_choices(rng, quality, position, random, m, noise, position_bias, tie_rate,
                            middle), categories=GRADED_CHOICES)
    elif study_type == "mushra":
        latent = (quality + rng.normal(0.0, 0.3, participants)[participant]
                  + noise * rng.logistic(size=n_rows))
        scores = 100 / (1 + np.exp(-(latent - centre)))
        reference = (row_source == n_sources - 2) & (rng.random(n_rows) >= MUSHRA_SLIPS)
        scores = np.where(reference, rng.uniform(90, 100, n_rows), scores)
        scores = np.where(random, rng.uniform(0, 100, n_rows), scores)
        table["score"] = pd.array(np.rint(scores).astype(np.int64), dtype="Int64")
    elif study_type == "best_of_k":
        table["pick"] = _picks(rng, quality, random, m, noise, tie_rate, middle)
    else:
        table["choice"] = pd.Categorical(_choices(rng, quality, position, random, m, noise,
                                                  position_bias, tie_rate, middle))

    shown = np.datetime64("2025-01-06T09:00:00") + (
        trial_participant * 3600 + trial_index * 20).astype("timedelta64[s]")
    seconds = np.where(fast[trial_participant], 0.3, rng.uniform(1.2, 3.0, len(trial_participant)))
    time_ms = np.rint(seconds * duration * 1000).astype(np.int64)
    answered = shown + (time_ms // 1000).astype("timedelta64[s]")
    is_catch = (kind == "catch") & (position == 0)
    # Catch clips are their own stimulus (an obviously broken clip), of source "catch".
    stimulus = np.where(is_catch, n_stimuli, stimulus)
    row_source = np.where(is_catch, n_sources, row_source)
    tokens = [f"t{i:05d}" for i in range(n_stimuli)] + ["catch"]
    kinds = pd.Categorical.from_codes(np.select([kind == "main", kind == "catch"], [0, 1], 2),
                                      ["main", "catch", "repeat"])
    trial_codes = row_trial
    frame = pd.DataFrame({
        "study": study,
        "study_type": study_type,
        "participant": participant + 1,
        "participant_seed": participant * 7919 % 100003,
        "trial": trial_index[row_trial],
        "trial_id": row_trial + 1,
        "action": pd.Categorical.from_codes(trial_action[row_trial], list(actions)),
        "stimulus": stimulus + 1,
        "stimulus_token": pd.Categorical.from_codes(stimulus, tokens),
        "source": pd.Categorical.from_codes(row_source, list(names) + ["catch"]),
        "motion_hash": pd.Categorical.from_codes(stimulus, tokens),
        "video_hash": pd.Categorical.from_codes(stimulus, tokens),
        "duration": duration,
        "position": position,
        "n_items": m,
        "trial_kind": kinds,
        "is_catch": is_catch,
        "stimulus_role": np.select(
            [is_catch, row_source == n_sources - 2, row_source == n_sources - 1],
            ["catch", "reference", "anchor"], "judged")
        if study_type == "mushra" else "judged",
        **table,
        "catch_passed": pd.arrays.BooleanArray(~random, kind != "catch"),
        "plays": 1,
        "time_ms": time_ms[row_trial],
        "shown_at": pd.Categorical.from_codes(trial_codes, np.datetime_as_string(shown)),
        "answered_at": pd.Categorical.from_codes(trial_codes, np.datetime_as_string(answered)),
        "completed": True,
    })
    order = np.lexsort((frame["position"].to_numpy(), frame["trial"].to_numpy(), participant))
    columns = list(RESPONSE_COLUMNS) + list(EXTRA_COLUMNS.get(study_type, ()))
    return frame.iloc[order].reset_index(drop=True)[columns]


def _trial_sources(study_type, rng, n_trials, n_sources, clips_per_trial) -> np.ndarray:
    """Return ``(trials, m)`` source indices shown in each trial."""
    if study_type in ("ranking", "rating_standards", "mushra"):
        return np.tile(np.arange(n_sources), (n_trials, 1))
    if study_type == "rating_reference":
        return rng.integers(0, n_sources, (n_trials, 1))
    if study_type == "fake_or_real":
        return rng.integers(0, n_sources, (n_trials, clips_per_trial))
    if study_type == "best_of_k":
        k = min(clips_per_trial, n_sources)
        return np.argsort(rng.random((n_trials, n_sources)), axis=1)[:, :k]
    if n_sources < 2:
        raise AnalysisError("a pairwise study needs at least two sources")
    first = rng.integers(0, n_sources, n_trials)
    second = (first + rng.integers(1, n_sources, n_trials)) % n_sources
    return np.stack([first, second], axis=1)


def _choices(rng, quality, position, random, m, noise, position_bias, tie_rate, middle):
    """Return each row's trial choice: left, right, both_good or both_bad."""
    q = quality.reshape(-1, m)
    left = position.reshape(-1, m) == 0
    q_left = np.where(left[:, 0], q[:, 0], q[:, 1])
    q_right = np.where(left[:, 0], q[:, 1], q[:, 0])
    chance = _sigmoid((q_left - q_right + position_bias) / noise)
    careless = random.reshape(-1, m)[:, 0]
    chance = np.where(careless, 0.5, chance)
    picks = np.where(rng.random(len(q)) < chance, "left", "right").astype(object)
    tie = (rng.random(len(q)) < tie_rate) & ~careless
    picks[tie] = np.where((q_left + q_right)[tie] / 2 > middle, "both_good", "both_bad")
    return np.repeat(picks, m)


def _graded_choices(rng, quality, position, random, m, noise, position_bias, tie_rate, middle):
    """Return each row's trial answer on the graded scale (grade of the left clip, cut from
    a logistic draw), or both_bad."""
    q = quality.reshape(-1, m)
    left = position.reshape(-1, m) == 0
    q_left = np.where(left[:, 0], q[:, 0], q[:, 1])
    q_right = np.where(left[:, 0], q[:, 1], q[:, 0])
    latent = q_left - q_right + position_bias + noise * rng.logistic(size=len(q))
    # Index into GRADED_CHOICES: 0 is "left much better" (grade +3), 6 "right much better".
    index = 6 - np.searchsorted(np.array([-2.5, -1.5, -0.5, 0.5, 1.5, 2.5]), latent)
    careless = random.reshape(-1, m)[:, 0]
    index = np.where(careless, rng.integers(0, 7, len(q)), index)
    bad = (rng.random(len(q)) < tie_rate) & ~careless & ((q_left + q_right) / 2 < middle)
    index[bad] = 7
    return np.repeat(np.asarray(GRADED_CHOICES, dtype=object)[index], m)
def _picks(rng, quality, random, m, noise, tie_rate, middle):
    """Return each row's pick: best, other, all_good or all_bad."""
    utility = np.where(random, 0.0, quality) + noise * rng.gumbel(size=len(quality))
    utility = utility.reshape(-1, m)
    picks = np.full(utility.shape, "other", dtype=object)
    picks[np.arange(len(utility)), utility.argmax(axis=1)] = "best"
    careless = random.reshape(-1, m)[:, 0]
    tie = (rng.random(len(utility)) < tie_rate) & ~careless
    good = quality.reshape(-1, m).mean(axis=1) > middle
    picks[tie] = np.where(good[tie], "all_good", "all_bad")[:, None]
    return picks.ravel()


def _missing(n: int, dtype):
    """Return ``n`` missing values of a nullable integer or boolean column."""
    values, mask = np.zeros(n, dtype=dtype), np.ones(n, dtype=bool)
    return pd.arrays.BooleanArray(values, mask) if dtype is bool else pd.arrays.IntegerArray(values, mask)


def _sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))
