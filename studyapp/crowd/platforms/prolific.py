"""Prolific: the entry link carries ``PROLIFIC_PID``, ``STUDY_ID`` and ``SESSION_ID`` (24
hex digits each, case-insensitive). With ``strict_ids`` (the default here) all three are
required, ``STUDY_ID`` must be the study's ``prolific_study_id`` once it has one
(``manage.py prolific create`` stores it) and one ``SESSION_ID`` takes the study once.
Each outcome has the study's own completion code (``codes``): a study that can end with
an outcome (``failed_attention`` when it has attention checks, ``no_consent`` always,
``screened_out`` with screening questions) must have its code, or it is refused. The
last page sends people to ``https://app.prolific.com/submissions/complete?cc=CODE``.
The study has a time limit unless it says otherwise (:func:`prolific_time_limit`). Its
API (drafts, review, bonuses) is :mod:`studyapp.crowd.prolific`.
"""

from __future__ import annotations

import hashlib
import math
import re
from urllib.parse import quote

from studyapp.crowd.platform import EntryRefused, Platform, registry

PROLIFIC_ID = re.compile(r"^[0-9a-f]{24}$")
# Prolific's policy: a study over this many minutes needs at least MIN_CHECKS attention
# checks, and a submission may be rejected only after MIN_CHECKS failed ones.
CHECKS_OVER_MINUTES = 5
MIN_CHECKS = 2

CODE_HELP = {
    "completed": "the code Prolific shows for completed submissions",
    "failed_attention": "this study has {checks} attention check(s) (catch_trials, "
                        "instructed_checks), so a participant can fail them",
    "no_consent": "a participant can decline on the consent page",
    "screened_out": "this study has screening questions (crowd.screening)",
}


def prolific_minimum_time(minutes: int) -> int:
    """Return the least maximum allowed time Prolific accepts for a study estimated at
    ``minutes``: 2 + X + 2 sqrt(X) minutes (its help centre, "Timed-out submissions")."""
    return math.ceil(2 + minutes + 2 * math.sqrt(minutes))


def prolific_time_limit(minutes: int) -> int:
    """Return the default time limit of a Prolific study estimated at ``minutes``: three
    times the estimate (30 for 10), never below Prolific's minimum."""
    return max(3 * minutes, prolific_minimum_time(minutes))


def session_params(study, person: str, study_id: str = "") -> list[tuple[str, str]]:
    """Return Prolific's ``STUDY_ID`` (``study_id``, or one made from the study) and a
    ``SESSION_ID`` made from ``person``, as Prolific's links carry them."""
    study_id = study_id or hashlib.sha1(f"study-{study.pk}".encode()).hexdigest()[:24]
    session = hashlib.sha1(f"session-{person}".encode()).hexdigest()[:24]
    return [("STUDY_ID", study_id), ("SESSION_ID", session)]


@registry.register("prolific")
class Prolific(Platform):
    label = "Prolific"
    redirects = True
    id_params = ("PROLIFIC_PID",)
    extra_params = ("STUDY_ID", "SESSION_ID")
    require_id = True
    strict_ids = True
    session_param = "SESSION_ID"
    id_format = PROLIFIC_ID
    own_settings = ("prolific_study_id",)
    example_settings = {"prolific_study_id": "64f0c0ffee0000000000beef"}
    example_person = "5f0c0ffee00000000000abcd"
    COMPLETE = "https://app.prolific.com/submissions/complete?cc={code}"

    def __init__(self, settings):
        super().__init__(settings)
        study_id = settings.get("prolific_study_id")
        if study_id is not None and not (isinstance(study_id, str)
                                         and PROLIFIC_ID.match(study_id.lower())):
            raise ValueError(f"crowd.prolific_study_id: {study_id!r} must be the 24 hex digits "
                             f"of the study's id on Prolific (in its page's address)")
        self.study_id = study_id.lower() if study_id else ""
        if "completed" not in self.codes:
            raise ValueError("crowd.codes.completed: a Prolific study needs the completion "
                             "code of its 'completed' outcome (from the study's page on "
                             "Prolific, or `manage.py prolific create`)")

    def check_codes(self, outcomes, checks=0):
        for outcome in outcomes:
            if outcome not in self.codes:
                why = CODE_HELP[outcome].format(checks=checks)
                raise ValueError(
                    f"crowd.codes.{outcome}: {why}, and a Prolific study gives each outcome "
                    f"its own code (never the completed one); add that code from the "
                    f"study's page on Prolific, or build the study without crowd.platform "
                    f"and let `manage.py prolific create` generate every code")

    def default_time_limit(self, estimate):
        return prolific_time_limit(estimate)

    def default_checks(self, estimate):
        return MIN_CHECKS if estimate > CHECKS_OVER_MINUTES else 0

    def warnings(self, estimate, checks, max_failed):
        out = []
        if estimate > CHECKS_OVER_MINUTES and checks < MIN_CHECKS:
            out.append(f"study: {checks} attention check(s) in a study estimated at {estimate} "
                       f"minutes; Prolific asks for at least {MIN_CHECKS} in a study over "
                       f"{CHECKS_OVER_MINUTES} minutes (set study.instructed_checks or "
                       f"catch_trials)")
        if checks and max_failed < MIN_CHECKS - 1:
            out.append(f"study.max_failed_catch: {max_failed} fails a participant after "
                       f"{max_failed + 1} failed check(s); Prolific allows a rejection only "
                       f"after {MIN_CHECKS} (max_failed_catch: {MIN_CHECKS - 1})")
        return out

    def normalise(self, name, value):
        return value.strip().lower()

    def read_ids(self, query):
        ids, key = super().read_ids(query)
        pid = ids.get("PROLIFIC_PID")
        if pid is not None and not PROLIFIC_ID.match(pid):
            raise EntryRefused("bad_id", "PROLIFIC_PID")
        if self.study_id and ids.get("STUDY_ID") != self.study_id:
            raise EntryRefused("wrong_study", "STUDY_ID")
        return ids, key

    def entry_params(self, study, person):
        return super().entry_params(study, person) + session_params(study, person, self.study_id)

    def completion_url(self, participant):
        code = participant.completion_code
        return self.COMPLETE.format(code=quote(code)) if code else ""

    def client(self):
        """Return a client of Prolific's API, its token from the environment."""
        from studyapp.crowd.prolific.client import Client

        return Client.from_env()

    def stop_recruiting(self, study):
        """Stop the study on Prolific (``POST /api/v1/studies/{id}/transition/`` with
        ``{"action": "STOP"}``): no new places; those taking part can still finish."""
        from studyapp.crowd.prolific.client import ProlificError

        if not self.study_id:
            return ("no Prolific study id in crowd.prolific_study_id: nothing sent to Prolific; "
                    "stop the study on its page there")
        try:
            answer = self.client().transition_study(self.study_id, "STOP")
        except (ProlificError, ValueError) as exc:
            return (f"Prolific study {self.study_id}: STOP failed ({exc}); stop it with "
                    f"manage.py prolific stop --study {study.slug}")
        return f"Prolific study {self.study_id}: STOP sent, status {(answer or {}).get('status', 'unknown')}"
