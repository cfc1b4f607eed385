"""Simulated response tables: raters with known source strengths, for every study type.

Each source has a Bradley-Terry strength (log scale); a clip's quality is its source's
strength plus a small clip effect. The shared part is here: participants, trials (main,
catch, repeats), actions, clips, screen positions, careless raters and speeders, times.
What a rater of a type sees and answers comes from the type's analysis plug-in
(:class:`analysis.registry.StudyAnalysis`): ``simulated_sources`` (controls added as
sources, e.g. a hidden reference), ``simulated_trials`` (the sources each trial shows),
``simulated_answers`` (the answer columns, drawn from :class:`Raters`) and
``simulated_roles``; each type's module says how its attentive raters answer.

Inattentive raters answer at random and fail every catch trial; speeders answer faster
than the clips last. The table has the columns of :mod:`analysis.tables` (and the type's
``extra_columns``), so the real analysis runs on it. Everything is vectorised: a million
judgements take about a second.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from dataclasses import dataclass

from analysis.registry import StudyAnalysis, get_analysis, list_analyses
from analysis.tables import RESPONSE_COLUMNS, AnalysisError

STRENGTHS = {"real": 4.0, "a2m": 3.0, "cond_gru": 1.0}
ACTIONS = ("walk", "eat", "jump", "sit")


@dataclass
class Raters:
    """What a type's ``simulated_answers`` draws from, one entry per row (judged clip).

    ``rng`` is the simulation's generator (draw from it in a fixed order: the table
    depends on it); ``quality`` the clip's latent quality, ``position`` its place on the
    screen, ``random`` whether its rater answers at random, ``participant`` its rater's
    index (of ``participants``), ``row_source`` its source's index (of ``n_sources``);
    ``m`` clips per trial (rows come in trials of ``m``); ``middle`` the middle of the
    shown sources' strengths, ``centre`` of the given ones (before controls were added).
    """

    rng: np.random.Generator
    quality: np.ndarray
    position: np.ndarray
    random: np.ndarray
    participant: np.ndarray
    participants: int
    row_source: np.ndarray
    n_sources: int
    strength: np.ndarray
    m: int
    noise: float
    position_bias: float
    tie_rate: float
    middle: float
    centre: float

    @property
    def n_rows(self) -> int:
        return len(self.quality)


def simulated_types() -> list[str]:
    """Return the study types whose analysis can simulate raters."""
    return [name for name in list_analyses() if can_simulate(get_analysis(name))]


def can_simulate(analysis: StudyAnalysis) -> bool:
    return type(analysis).simulated_answers is not StudyAnalysis.simulated_answers


def __getattr__(name):
    # Read from the registry when asked, not at import (the registry imports this module).
    if name == "STUDY_TYPES":
        return tuple(simulated_types())
    if name == "EXTRA_COLUMNS":
        return {t: get_analysis(t).extra_columns for t in simulated_types()
                if get_analysis(t).extra_columns}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def simulate(study_type: str, strengths: dict | None = None, participants: int = 200,
             trials: int = 10, *, actions=ACTIONS, clips_per_source: int = 5,
             clips_per_trial: int = 6, noise: float = 1.0, clip_sd: float = 0.3,
             inattentive: float = 0.0, speeders: float = 0.0, catch_trials: int = 0,
             repeat_trials: int = 0, position_bias: float = 0.0, tie_rate: float = 0.1,
             duration: float = 2.0, seed: int = 0, study: str = "simulated") -> pd.DataFrame:
    """Return a response table of ``participants`` x ``trials`` main trials of ``study_type``.

    ``strengths`` maps source to log-strength (default :data:`STRENGTHS`);
    ``clips_per_trial`` applies to the types whose trials draw that many clips (the type's
    ``simulated_trials`` says: others show one clip per source, one clip, or two). ``inattentive`` and
    ``speeders`` are the shares of such raters; each rater also gets ``catch_trials``
    catch trials and ``repeat_trials`` repeats of their first main trials.
    """
    known = simulated_types()
    if study_type not in known:
        raise AnalysisError(f"cannot simulate {study_type!r}; choose from {', '.join(known)}")
    plugin = get_analysis(study_type)
    strengths = dict(STRENGTHS if strengths is None else strengths)
    if participants < 1 or trials < 1 or len(strengths) < 1:
        raise AnalysisError("simulate at least one participant, one trial and one source")
    rng = np.random.default_rng(seed)
    names = np.array(list(strengths), dtype=object)
    strength = np.array(list(strengths.values()), dtype=float)
    centre = (strength.min() + strength.max()) / 2
    names, strength = plugin.simulated_sources(names, strength)
    actions = np.asarray(actions, dtype=object)
    n_sources = len(names)

    # Trials: main, then catch, then repeats of the first main trials, per participant.
    per_participant = trials + catch_trials
    n_trials = participants * per_participant
    trial_participant = np.repeat(np.arange(participants), per_participant)
    trial_index = np.tile(np.arange(per_participant), participants)
    trial_action = rng.integers(0, len(actions), n_trials)
    sources = plugin.simulated_trials(rng, n_trials, n_sources, clips_per_trial)
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
    table = {"rank": missing(n_rows, np.int64), "rating": missing(n_rows, np.int64),
             "judged_real": missing(n_rows, bool),
             "choice": pd.Categorical.from_codes(np.full(n_rows, -1),
                                                 ["left", "right", "both_good", "both_bad"])}
    middle = (strength.min() + strength.max()) / 2
    raters = Raters(rng=rng, quality=quality, position=position, random=random,
                    participant=participant, participants=participants, row_source=row_source,
                    n_sources=n_sources, strength=strength, m=m, noise=noise,
                    position_bias=position_bias, tie_rate=tie_rate, middle=middle, centre=centre)
    table.update(plugin.simulated_answers(raters))

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
        "stimulus_role": plugin.simulated_roles(is_catch, row_source, n_sources),
        **table,
        "catch_passed": pd.arrays.BooleanArray(~random, kind != "catch"),
        "plays": 1,
        "time_ms": time_ms[row_trial],
        "shown_at": pd.Categorical.from_codes(trial_codes, np.datetime_as_string(shown)),
        "answered_at": pd.Categorical.from_codes(trial_codes, np.datetime_as_string(answered)),
        "completed": True,
    })
    order = np.lexsort((frame["position"].to_numpy(), frame["trial"].to_numpy(), participant))
    frame["simulated"] = True  # reports say their participants were simulated
    columns = list(RESPONSE_COLUMNS) + list(plugin.extra_columns) + ["simulated"]
    return frame.iloc[order].reset_index(drop=True)[columns]


def every_source(n_trials: int, n_sources: int) -> np.ndarray:
    """Return trials showing one clip of every source."""
    return np.tile(np.arange(n_sources), (n_trials, 1))


def pairs(rng, n_trials: int, n_sources: int) -> np.ndarray:
    """Return trials of two clips of distinct sources, drawn at random."""
    if n_sources < 2:
        raise AnalysisError("a pairwise study needs at least two sources")
    first = rng.integers(0, n_sources, n_trials)
    second = (first + rng.integers(1, n_sources, n_trials)) % n_sources
    return np.stack([first, second], axis=1)


def left_right(raters: Raters):
    """Return per trial the left and the right clip's quality and whether its rater is careless."""
    q = raters.quality.reshape(-1, raters.m)
    left = raters.position.reshape(-1, raters.m) == 0
    q_left = np.where(left[:, 0], q[:, 0], q[:, 1])
    q_right = np.where(left[:, 0], q[:, 1], q[:, 0])
    return q_left, q_right, raters.random.reshape(-1, raters.m)[:, 0]


def missing(n: int, dtype):
    """Return ``n`` missing values of a nullable integer or boolean column."""
    values, mask = np.zeros(n, dtype=dtype), np.ones(n, dtype=bool)
    return pd.arrays.BooleanArray(values, mask) if dtype is bool else pd.arrays.IntegerArray(values, mask)


def sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))
