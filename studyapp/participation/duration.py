"""How long a study takes: estimated from the study itself, then measured.

The estimate plans one participant's session with the study type's own planner (practice,
catch, instructed and repeated trials included) and adds, per trial, the time its page
requires: every required clip played through once, one clip after another (the server's
watch gate lets no answer in before the clips could play; a person watches them in
turn), the type's
answer time (:meth:`StudyType.answer_time`) and a few seconds to read the question; then
the consent, instructions and closing pages. Once ``MEASURED_AFTER`` participants have
completed the study (a pilot, or the first participants), the median of their session
times (consent to completion) replaces the estimate. Consent text, the crowd platform's
time limit and attention-check advice and ``prolific create`` all read
``Study.minutes()``.

Before a build (the config check) the clips do not exist yet: :func:`config_minutes`
estimates from what the config says, assuming ``DEFAULT_CLIP_SECONDS`` and
``DEFAULT_TRIALS`` where it leaves the clip length or the number of trials to the data.
"""

from __future__ import annotations

import math
import random
import statistics
from dataclasses import dataclass

# Seconds of the pages around the trials.
CONSENT_SECONDS = 20
INSTRUCTION_SECONDS = 30
CLOSING_SECONDS = 5  # the last page (the completion code, the way back)
DEMOGRAPHICS_SECONDS = 30
# Seconds per trial to read the question (and an instructed check's sentence).
READ_SECONDS = 2
# Completed participants after whom their median time replaces the estimate.
MEASURED_AFTER = 5
# What the config check assumes where a config leaves it to the data.
DEFAULT_CLIP_SECONDS = 3.0
DEFAULT_TRIALS = 10


@dataclass(frozen=True)
class Duration:
    """A study's estimated seconds, the measured median (None before ``MEASURED_AFTER``
    completions) and how many completions it is the median of."""

    estimate: float
    measured: float | None = None
    n_measured: int = 0
    trials: int = 0

    @property
    def seconds(self) -> float:
        return self.measured if self.measured is not None else self.estimate

    @property
    def minutes(self) -> int:
        """Whole minutes, to the nearest, at least 1."""
        return whole_minutes(self.seconds)

    @property
    def estimate_minutes(self) -> int:
        return whole_minutes(self.estimate)

    def describe(self) -> str:
        estimate = f"estimated {format_seconds(self.estimate)} ({self.trials} trials)"
        if self.measured is None:
            return (f"{estimate}; measured after {MEASURED_AFTER} completed participants "
                    f"({self.n_measured} so far)")
        return (f"measured {format_seconds(self.measured)} (median of {self.n_measured} "
                f"completed participants); {estimate}")


def whole_minutes(seconds: float) -> int:
    """Return ``seconds`` in whole minutes, to the nearest (halves up), at least 1."""
    return max(1, math.floor(seconds / 60 + 0.5))


def format_seconds(seconds: float) -> str:
    seconds = round(seconds)
    return f"{seconds // 60} min {seconds % 60:02d} s" if seconds >= 60 else f"{seconds} s"


def fixed_seconds(ask_demographics: bool) -> float:
    """Return the seconds of the pages around the trials."""
    return (CONSENT_SECONDS + INSTRUCTION_SECONDS + CLOSING_SECONDS
            + (DEMOGRAPHICS_SECONDS if ask_demographics else 0))


def trial_seconds(kind, study, clip_seconds: list[float], n_judged: int) -> float:
    """Return the expected seconds of one trial whose page requires the clips of
    ``clip_seconds`` played through, with ``n_judged`` clips to answer about."""
    return READ_SECONDS + sum(clip_seconds) + kind.answer_time(study, n_judged)


def session_seconds(study) -> tuple[float, list[tuple[str, float]]]:
    """Return the seconds of the pages around the trials and, per trial of a session of
    ``study`` planned as a new participant's would be, its kind and expected seconds."""
    kind = study.kind
    trials = []
    for plan in kind.plan_trials(study, random.Random(0)):
        clips = [stimulus.duration for stimulus in plan.stimuli]
        clips += [stimulus.duration for stimulus, _, required in plan.shown if required]
        trials.append((str(plan.kind), trial_seconds(kind, study, clips, len(plan.stimuli))))
    return fixed_seconds(study.ask_demographics), trials


def estimate_seconds(study) -> tuple[float, int]:
    """Return the estimated seconds of one session of ``study`` and its trials, from a
    session planned as a new participant's would be."""
    fixed, trials = session_seconds(study)
    return fixed + sum(seconds for _, seconds in trials), len(trials)


def measured_seconds(times: list[float]) -> float | None:
    """Return the median of completed participants' session ``times`` (seconds), None
    below ``MEASURED_AFTER`` of them."""
    return statistics.median(times) if len(times) >= MEASURED_AFTER else None


def study_duration(study, times: list[float]) -> Duration:
    """Return the estimate of a saved ``study`` and, once its completed participants'
    session ``times`` are enough, their median."""
    estimate, trials = estimate_seconds(study)
    return Duration(estimate, measured_seconds(times), len(times), trials)


def config_minutes(study, conditions: int | None, clip_seconds: float | None) -> int:
    """Return the minutes a study config is estimated at before its build: ``study`` an
    unsaved study of its settings, ``conditions`` its actions or prompts (None: the data
    decides, ``DEFAULT_TRIALS`` trials assumed), ``clip_seconds`` the clip length (None:
    ``DEFAULT_CLIP_SECONDS``)."""
    kind = study.kind
    main = study.trials_per_participant or conditions or DEFAULT_TRIALS
    trials = (main + bool(study.practice) + (study.catch_trials or 0)
              + (study.instructed_checks or 0) + min(study.repeat_trials or 0, main))
    n = kind.items_per_trial(study)
    seconds = clip_seconds or DEFAULT_CLIP_SECONDS
    total = fixed_seconds(study.ask_demographics)
    total += trials * trial_seconds(kind, study, [seconds] * n, n)
    return whole_minutes(total)


# The Study fields of a config's study section that the estimate reads.
SETTINGS = ("clips_per_trial", "trials_per_participant", "practice", "catch_trials",
            "instructed_checks", "repeat_trials", "ask_demographics", "criteria")
