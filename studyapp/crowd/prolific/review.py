"""What to do with each Prolific submission, decided from our participants.

A submission is matched to our participant by its Prolific id (``participant_id``, the
``PROLIFIC_PID`` our entry link received). The decision never rests on the completion
code a submission carries (a code can be copied); it rests on our participant's
``outcome`` and on the analysis' participant-level exclusion rules
(:mod:`analysis.exclusions`: more than ``max_failed_catch`` failed catch trials; with
``max_failed_repeats``, more than that many repeated trials answered differently):

- a submission still ACTIVE or RESERVED, or already APPROVED, REJECTED, RETURNED,
  TIMED-OUT or SCREENED OUT: nothing is done;
- awaiting review, of someone we do not know, or who has no outcome yet (still taking
  part with us) or timed out: left for the researcher (never acted on);
- completed and kept by the exclusion rules: approved;
- failed the attention checks (their outcome, or an exclusion rule): a return is asked
  for, or with ``reject_failed`` the submission is rejected (category FAILED_CHECK) when
  at least two checks were failed (Prolific allows a rejection only then; with fewer, a
  return is asked for);
- declined consent or screened out: a return is asked for, unless it already was;
- of a participant of ours who came with another ``SESSION_ID`` than this submission's
  id: left for the researcher.

:func:`unknown_ids` lists our participants whose ids Prolific does not know: no
submission of that ``PROLIFIC_PID`` in the study, or none with their ``SESSION_ID``
(someone who made an id up to take the study again).

Run twice, the second run finds every submission it acted on already approved,
rejected or with its return requested, and does nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from studyapp.crowd.platforms.prolific import MIN_CHECKS
from studyapp.results.export import participants_frame
from studyapp.survey.models import Participant

APPROVE, RETURN, REJECT, NOTHING, LEAVE = "approve", "request return", "reject", "nothing", "leave"
IN_PROGRESS = ("ACTIVE", "RESERVED")
AWAITING = "AWAITING REVIEW"
REJECT_CATEGORY = "FAILED_CHECK"
DEFAULT_REJECT_MESSAGE = (
    "Thank you for taking part. Your submission is rejected because it did not pass the "
    "study's attention checks (trials showing an obviously broken clip, or a trial shown "
    "again) as often as the instructions and the study require.")
FAILED_REASON = "Failed the study's attention checks."
RETURN_REASON = {"no_consent": "Withdrew consent.", "screened_out": "Screened out.",
                 "failed_attention": FAILED_REASON}


@dataclass(frozen=True)
class Rules:
    """The analysis' participant-level exclusion rules (analysis/exclusions.py, rules 2 and
    2b), with the thresholds ``analyze`` takes as ``--max-failed-catch`` and
    ``--max-failed-repeats`` (None: repeats are counted, not applied)."""

    max_failed_catch: int = 1
    max_failed_repeats: int | None = None

    def __post_init__(self):
        if self.max_failed_catch < 0 or (self.max_failed_repeats or 0) < 0:
            raise ValueError("--max-failed-catch and --max-failed-repeats must be 0 or more")


@dataclass
class Decision:
    """What to do with one submission, and why (shown to the researcher)."""

    submission: dict
    action: str
    why: str
    participant: int | None = None
    outcome: str = ""
    note: str = ""

    @property
    def submission_id(self) -> str:
        return str(self.submission.get("id", ""))

    @property
    def prolific_id(self) -> str:
        return str(self.submission.get("participant_id") or self.submission.get("participant")
                   or "")


def text(value) -> str:
    """Return a table cell as text ("" for a missing one)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return str(value).strip()


def participant_index(study) -> dict[str, dict]:
    """Return ``{Prolific id: our participant's row}`` (pk, outcome, code, checks)."""
    table = participants_frame(study)
    out = {}
    if "PROLIFIC_PID" not in table.columns:
        return out
    for row in table.to_dict("records"):
        pid = text(row.get("PROLIFIC_PID")).lower()
        if pid:
            out[pid] = row
    return out


def unknown_ids(study, submissions: list[dict]) -> list[tuple[dict, str]]:
    """Return ``(row, why)`` of each participant of ours whose ids Prolific does not know:
    no submission of their ``PROLIFIC_PID`` in this study, or none whose id is their
    ``SESSION_ID`` (a made-up id, to take the study again)."""
    sessions: dict[str, set] = {}
    for s in submissions:
        pid = str(s.get("participant_id") or s.get("participant") or "").lower()
        sessions.setdefault(pid, set()).add(str(s.get("id", "")).lower())
    out = []
    for pid, row in participant_index(study).items():
        session = text(row.get("SESSION_ID")).lower()
        if pid not in sessions:
            out.append((row, f"no submission of {pid} on Prolific"))
        elif session and session not in sessions[pid]:
            out.append((row, f"{pid} has no submission {session} on Prolific"))
    return out


def exclusion(row: dict, config: Rules) -> str:
    """Return why the analysis' participant rules exclude ``row`` ("" when they keep it)."""
    failed = int(row.get("failed_catch") or 0)
    if failed > config.max_failed_catch:
        return (f"failed {failed} of {int(row.get('n_catch') or 0)} attention check(s), more "
                f"than {config.max_failed_catch}")
    limit = config.max_failed_repeats
    changed = int(row.get("inconsistent_repeats") or 0)
    if limit is not None and changed > limit:
        return f"answered {changed} repeated trial(s) differently, more than {limit}"
    return ""


def decide(submission: dict, people: dict[str, dict], config: Rules,
           reject_failed: bool = False) -> Decision:
    """Return the :class:`Decision` for one submission (see the module docstring)."""
    status = str(submission.get("status") or "")
    pid = str(submission.get("participant_id") or submission.get("participant") or "").lower()
    row = people.get(pid)
    number = int(row["participant"]) if row else None
    outcome = str(row.get("outcome") or "") if row else ""

    entered = str(submission.get("study_code") or submission.get("entered_code") or "")
    ours = str(row.get("completion_code") or "") if row else ""
    note = f"entered code {entered or 'none'}, we gave {ours}" if ours and entered != ours else ""

    def decision(action, why):
        return Decision(submission, action, why, number, outcome, note)

    if status in IN_PROGRESS:
        return decision(NOTHING, "still taking part on Prolific")
    if status != AWAITING:
        return decision(NOTHING, f"already {status or 'without a status'} on Prolific")
    if row is None:
        return decision(LEAVE, "not a participant of ours: review it on Prolific")
    if not outcome:
        return decision(LEAVE, "still taking part in our study (no outcome yet)")
    if outcome == Participant.Outcome.TIMED_OUT:
        return decision(LEAVE, "ran out of time in our study")
    session = text(row.get("SESSION_ID")).lower()
    if session and session != str(submission.get("id", "")).lower():
        return decision(LEAVE, f"our participant came with session {session}, not this "
                               f"submission: review it on Prolific")
    returned = bool(submission.get("return_requested"))
    if outcome in (Participant.Outcome.NO_CONSENT, Participant.Outcome.SCREENED_OUT):
        if returned:
            return decision(NOTHING, f"{outcome}: return already requested")
        return decision(RETURN, outcome)
    why = "failed the attention checks" if outcome == Participant.Outcome.FAILED_ATTENTION \
        else exclusion(row, config)
    if outcome == Participant.Outcome.COMPLETED and not why:
        return decision(APPROVE, "completed")
    failed = int(row.get("failed_catch") or 0)
    if reject_failed and failed >= MIN_CHECKS:
        return decision(REJECT, why)
    if reject_failed:
        why += (f"; {failed} failed check(s): Prolific allows a rejection only after "
                f"{MIN_CHECKS}, so a return is asked for")
    if returned:
        return decision(NOTHING, f"{why}: return already requested")
    return decision(RETURN, why)


def plan(study, submissions: list[dict], config: Rules,
         reject_failed: bool = False) -> list[Decision]:
    """Return one decision per submission, in Prolific's order."""
    people = participant_index(study)
    return [decide(s, people, config, reject_failed) for s in submissions]
