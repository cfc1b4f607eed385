"""A draft Prolific study made from one of ours: its payload and completion codes.

Each of our outcomes gets a completion code whose type and actions are Prolific's
("The study object", ``completion_codes``: ``code``, ``code_type``, ``actor``,
``actions``):

=================  ======================  =========================================
our outcome        code_type               actions
=================  ======================  =========================================
completed          COMPLETED               AUTOMATICALLY_APPROVE (MANUALLY_REVIEW with
                                           ``review_completed``, for ``review`` to decide)
failed_attention   FAILED_ATTENTION_CHECK  MANUALLY_REVIEW (``review`` rejects or asks
                                           for a return, as the researcher chooses)
no_consent         NO_CONSENT              REQUEST_RETURN, reason "Withdrew consent."
screened_out       OTHER                   REQUEST_RETURN, reason "Screened out."; or,
                   or FIXED_SCREENOUT      with ``screen_out_reward``, FIXED_SCREENOUT
                                           with FIXED_SCREEN_OUT_PAYMENT (a fixed
                                           screen-out payment; not every workspace has it)
=================  ======================  =========================================

``timed_out`` has no code: Prolific times people out itself. The draft's maximum allowed
time is the study's ``crowd.time_limit_minutes``, by default
:func:`~studyapp.crowd.platforms.prolific.prolific_time_limit` of the estimated time (stored in the
study by ``create``, so both time people out alike).
"""

from __future__ import annotations

import math
import secrets
from dataclasses import dataclass

from studyapp.crowd.platform import OUTCOMES
from studyapp.crowd.platforms.prolific import prolific_minimum_time, prolific_time_limit

PLACEHOLDERS = ("?PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}"
                "&SESSION_ID={{%SESSION_ID%}}")
DEVICES = ("desktop", "tablet", "mobile")
DEFAULT_HOURLY_CENTS = 900
RETURN_REASONS = {"no_consent": "Withdrew consent.", "screened_out": "Screened out."}


@dataclass
class DraftOptions:
    """What the researcher chose for the draft (``manage.py prolific create`` options)."""

    base_url: str
    places: int | None = None
    minutes: int | None = None
    reward_cents: int | None = None
    hourly_cents: int = DEFAULT_HOURLY_CENTS
    description: str = ""
    devices: tuple[str, ...] = DEVICES
    review_completed: bool = False
    screen_out_reward_cents: int | None = None


def new_code(taken=()) -> str:
    """Return a completion code like Prolific's own (C and 7 hex digits), not in ``taken``."""
    while True:
        code = "C" + secrets.token_hex(4).upper()[:7]
        if code not in taken:
            return code


def outcomes_of(study) -> list[str]:
    """Return the outcomes a participant of ``study`` can end with and be sent back with."""
    screening = bool((study.crowd or {}).get("screening"))
    return [o for o in OUTCOMES if o != "screened_out" or screening]


def fill_codes(study) -> tuple[dict, list[str]]:
    """Return the study's codes with a new one for each outcome that has none, and the
    outcomes given a new code."""
    codes = dict((study.crowd or {}).get("codes") or {})
    made = []
    for outcome in outcomes_of(study):
        if not codes.get(outcome):
            codes[outcome] = new_code(set(codes.values()))
            made.append(outcome)
    return codes, made


def time_limit_of(study, minutes: int) -> int | None:
    """Return the maximum allowed time of the draft (None: Prolific's own): the study's
    ``time_limit_minutes``, else the default for a Prolific study of ``minutes``."""
    crowd = study.crowd or {}
    if "time_limit_minutes" in crowd:
        return crowd["time_limit_minutes"]
    return prolific_time_limit(minutes)


def external_url(study, base_url: str) -> str:
    """Return our participant link with Prolific's three placeholders."""
    return study.participant_url(base_url) + PLACEHOLDERS


def completion_codes(codes: dict, options: DraftOptions, places: int) -> list[dict]:
    """Return Prolific's ``completion_codes`` for our outcomes' codes (module docstring)."""
    out = []
    if "completed" in codes:
        action = "MANUALLY_REVIEW" if options.review_completed else "AUTOMATICALLY_APPROVE"
        out.append(_code(codes["completed"], "COMPLETED", [{"action": action}]))
    if "failed_attention" in codes:
        out.append(_code(codes["failed_attention"], "FAILED_ATTENTION_CHECK",
                         [{"action": "MANUALLY_REVIEW"}]))
    if "no_consent" in codes:
        out.append(_code(codes["no_consent"], "NO_CONSENT", [
            {"action": "REQUEST_RETURN", "return_reason": RETURN_REASONS["no_consent"]}]))
    if "screened_out" in codes:
        if options.screen_out_reward_cents is not None:
            action = {"action": "FIXED_SCREEN_OUT_PAYMENT",
                      "fixed_screen_out_reward": options.screen_out_reward_cents,
                      "slots": places}
            out.append(_code(codes["screened_out"], "FIXED_SCREENOUT", [action]))
        else:
            out.append(_code(codes["screened_out"], "OTHER", [
                {"action": "REQUEST_RETURN",
                 "return_reason": RETURN_REASONS["screened_out"]}]))
    return out


def _code(code: str, code_type: str, actions: list[dict]) -> dict:
    return {"code": code, "code_type": code_type, "actor": "participant", "actions": actions}


def reward_for(minutes: int, hourly_cents: int) -> int:
    """Return the reward in cents of ``minutes`` paid at ``hourly_cents`` an hour."""
    return math.ceil(minutes * hourly_cents / 60)


def draft_payload(study, codes: dict, options: DraftOptions) -> dict:
    """Return the body of ``POST /api/v1/studies/`` for ``study``; ValueError when a
    value is missing or out of range (the message names the option)."""
    places = options.places if options.places is not None else study.max_participants
    if not places or places < 1:
        raise ValueError(f"study {study.slug} has no max_participants: say how many people "
                         f"Prolific should recruit with --places N")
    minutes = options.minutes if options.minutes is not None else study.minutes()
    if minutes < 1:
        raise ValueError(f"--minutes {minutes}: the estimated time must be at least 1 minute")
    reward = options.reward_cents
    if reward is None:
        reward = reward_for(minutes, options.hourly_cents)
    if reward < 0:
        raise ValueError(f"--reward-cents {reward}: a reward cannot be negative")
    screen_out = options.screen_out_reward_cents
    if screen_out is not None and not 0 < screen_out < reward:
        raise ValueError(f"--screen-out-reward-cents {screen_out}: must be more than 0 and "
                         f"less than the reward ({reward})")
    unknown = sorted(set(options.devices) - set(DEVICES))
    if unknown or not options.devices:
        raise ValueError(f"--devices: {', '.join(unknown) or 'none given'}; choose among "
                         f"{', '.join(DEVICES)}")
    payload = {
        "name": study.title,
        "internal_name": study.slug,
        "description": options.description or study.shown_consent(),
        "external_study_url": external_url(study, options.base_url),
        "prolific_id_option": "url_parameters",
        "completion_codes": completion_codes(codes, options, places),
        "total_available_places": places,
        "estimated_completion_time": minutes,
        "reward": reward,
        "device_compatibility": list(options.devices),
        "peripheral_requirements": [],
        "filters": [],
        "submissions_config": {"max_submissions_per_participant": 1},
    }
    limit = time_limit_of(study, minutes)
    if limit:
        least = prolific_minimum_time(minutes)
        if limit < least:
            raise ValueError(f"crowd.time_limit_minutes {limit} is shorter than Prolific "
                             f"allows for the estimated {minutes} minutes (at least 2 + X + "
                             f"2 sqrt(X) = {least}): raise it or pass --minutes")
        payload["maximum_allowed_time"] = limit
    return payload
