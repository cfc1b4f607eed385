"""Crowd platforms: who a participant is, and where they go with which code at the end.

A study's ``crowd`` field names its platform and that platform's settings:

- ``prolific``: the entry link carries ``PROLIFIC_PID``, ``STUDY_ID`` and ``SESSION_ID``
  (24 hex digits each, case-insensitive). With ``strict_ids`` (the default here) all three
  are required, ``STUDY_ID`` must be the study's ``prolific_study_id`` once it has one
  (``manage.py prolific create`` stores it) and one ``SESSION_ID`` takes the study once.
  Each outcome has the study's own completion code (``codes``), and the last page sends
  people to ``https://app.prolific.com/submissions/complete?cc=CODE``. The study has a
  time limit unless it says otherwise (:func:`prolific_time_limit`).
- ``generic``: any other platform (CloudResearch Connect, SONA, a panel of your own):
  ``id_param`` names the query parameter that identifies a person, ``extra_params`` are
  recorded too, ``completion_url_template`` is where people go at the end, with
  ``{code}`` and ``{id}`` filled in.
- no platform (an empty ``crowd``): ``PROLIFIC_PID`` or ``participant_label`` identify a
  person when present; the completion page shows a random code and links to the study's
  ``completion_url``.

A completion code is only ever the code of the participant's own outcome. On Prolific a
study that can end with an outcome (``failed_attention`` when it has attention checks,
``no_consent`` always, ``screened_out`` with screening questions) must have its code, or
it is refused (:meth:`Platform.check_codes`, asked by the build's config check and the
admin). Elsewhere a completed session without its own code gets a random one and any
other outcome without its own code gets none (and no link to the platform's completion
URL, which could credit the person). ``timed_out`` never has a code: Prolific times
people out itself, and a code would let them submit.

Common settings: ``codes`` (``completed``, ``failed_attention``, ``no_consent``,
``screened_out``), ``time_limit_minutes`` (a participant who consented longer ago and has
not finished loses their place and can no longer answer, as Prolific times them out;
``null``: no limit), ``idle_minutes`` (default 10: a participant who consented and has
not answered a trial for this long loses their place the same way; ``null``: never),
``screening`` (questions on the consent page; an answer not accepted ends the session
with the ``screened_out`` outcome), ``require_id`` and ``strict_ids`` (the platform's
ids required, well-formed and, for a session id, unique).
"""

from __future__ import annotations

import math
import re
from datetime import timedelta
from urllib.parse import quote

from generation.registry import Registry

# Outcomes a completion code can belong to; ``timed_out`` is the one without.
OUTCOMES = ("completed", "failed_attention", "no_consent", "screened_out")
SETTINGS = ("platform", "codes", "time_limit_minutes", "idle_minutes", "id_param",
            "extra_params", "completion_url_template", "require_id", "strict_ids",
            "screening", "prolific_study_id")
MAX_ID_LENGTH = 100
PROLIFIC_ID = re.compile(r"^[0-9a-f]{24}$")
# What a well-formed id of a platform without its own format may hold.
PLAIN_ID = re.compile(r"^[A-Za-z0-9_.:@-]{1,100}$")
DEFAULT_IDLE_MINUTES = 10
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

registry = Registry("crowd platform")


class EntryRefused(Exception):
    """The entry link cannot start a session; ``reason`` picks the page, ``detail`` says why."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(detail or reason)
        self.reason, self.detail = reason, detail


def _printable(value: str) -> str:
    # Control characters (a NUL byte above all, which PostgreSQL refuses in text) are
    # never part of a platform's ids: drop them rather than fail.
    return "".join(c for c in value if c.isprintable()).strip()[:MAX_ID_LENGTH]


def outcomes_of(checks: int, screening: bool) -> list[str]:
    """Return the outcomes with a code a study can end with: ``completed`` and
    ``no_consent`` always, ``failed_attention`` with ``checks`` attention checks,
    ``screened_out`` with screening questions."""
    return [o for o in OUTCOMES if (o != "failed_attention" or checks)
            and (o != "screened_out" or screening)]


def prolific_minimum_time(minutes: int) -> int:
    """Return the least maximum allowed time Prolific accepts for a study estimated at
    ``minutes``: 2 + X + 2 sqrt(X) minutes (its help centre, "Timed-out submissions")."""
    return math.ceil(2 + minutes + 2 * math.sqrt(minutes))


def prolific_time_limit(minutes: int) -> int:
    """Return the default time limit of a Prolific study estimated at ``minutes``: three
    times the estimate (30 for 10), never below Prolific's minimum."""
    return max(3 * minutes, prolific_minimum_time(minutes))


def _minutes(settings: dict, name: str) -> None:
    value = settings.get(name)
    if value is not None and (isinstance(value, bool) or not isinstance(value, int)
                              or value < 1):
        raise ValueError(f"crowd.{name}: {value!r} must be a whole number of minutes, at "
                         f"least 1 (or null for none)")


class Platform:
    """What a study's crowd platform decides: ids at entry, codes and the way out.

    ``redirects``: the last page sends people on by itself (a platform's own completion
    URL); otherwise it only links to the study's ``completion_url``. ``session_param``
    names the id of one visit (unique per study with ``strict_ids``).
    """

    label = "the study platform"
    redirects = False
    id_params: tuple[str, ...] = ("PROLIFIC_PID", "participant_label")
    extra_params: tuple[str, ...] = ("STUDY_ID", "SESSION_ID")
    require_id = False
    strict_ids = False
    session_param = ""
    id_format = PLAIN_ID

    def __init__(self, settings: dict):
        settings = dict(settings or {})
        unknown = sorted(set(settings) - set(SETTINGS))
        if unknown:
            raise ValueError(f"crowd.{unknown[0]}: unknown setting; settings are "
                             f"{', '.join(SETTINGS)}")
        self.settings = settings
        codes = settings.get("codes") or {}
        if not isinstance(codes, dict):
            raise ValueError(f"crowd.codes: {codes!r} must map outcomes to codes, e.g. "
                             f"{{completed: C1A2B3C4, failed_attention: C9X8Y7Z6}}")
        if "timed_out" in codes:
            raise ValueError("crowd.codes.timed_out: a participant who runs out of time gets "
                             "no code (the platform times them out itself, and a code would "
                             "let them submit); remove it")
        bad = sorted(set(codes) - set(OUTCOMES))
        if bad:
            raise ValueError(f"crowd.codes.{bad[0]}: not an outcome; outcomes are "
                             f"{', '.join(OUTCOMES)}")
        for outcome, code in codes.items():
            if not isinstance(code, str) or not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", code):
                raise ValueError(f"crowd.codes.{outcome}: {code!r} must be 1 to 64 letters, "
                                 f"digits, - or _")
        self.codes = dict(codes)
        _minutes(settings, "time_limit_minutes")
        _minutes(settings, "idle_minutes")
        for name in ("require_id", "strict_ids"):
            if name in settings:
                if not isinstance(settings[name], bool):
                    raise ValueError(f"crowd.{name}: {settings[name]!r} must be true or false")
                setattr(self, name, settings[name])
        study_id = settings.get("prolific_study_id")
        if study_id is not None and not (isinstance(study_id, str)
                                         and PROLIFIC_ID.match(study_id.lower())):
            raise ValueError(f"crowd.prolific_study_id: {study_id!r} must be the 24 hex digits "
                             f"of the study's id on Prolific (in its page's address)")
        self.prolific_study_id = study_id.lower() if study_id else ""
        self.screening = self._screening(settings.get("screening") or [])

    @staticmethod
    def _screening(questions) -> list[dict]:
        if not isinstance(questions, list):
            raise ValueError("crowd.screening: must be a list of {question, answers, accept}")
        out = []
        for i, q in enumerate(questions):
            where = f"crowd.screening.{i}"
            if not isinstance(q, dict) or not isinstance(q.get("question"), str):
                raise ValueError(f"{where}: needs a question text")
            answers = q.get("answers") or ["Yes", "No"]
            accept = q.get("accept") or answers[:1]
            if not set(accept) <= set(answers):
                raise ValueError(f"{where}.accept: {accept!r} must be among its answers "
                                 f"{answers!r}")
            out.append({"question": q["question"], "answers": list(answers),
                        "accept": list(accept)})
        return out

    # The study

    def check_codes(self, outcomes, checks: int = 0) -> None:
        """Raise ValueError naming ``crowd.codes.<outcome>`` for an outcome of ``outcomes``
        (those the study can end with) that needs a code this platform lacks."""

    def time_limit(self, estimate: int) -> timedelta | None:
        """Return the study's time limit: ``time_limit_minutes``, else the platform's
        default for a study estimated at ``estimate`` minutes; None for no limit."""
        if "time_limit_minutes" in self.settings:
            minutes = self.settings["time_limit_minutes"]
        else:
            minutes = self.default_time_limit(estimate)
        return timedelta(minutes=minutes) if minutes else None

    def default_time_limit(self, estimate: int) -> int | None:
        return None

    def default_checks(self, estimate: int) -> int:
        """Return the instructed checks a study estimated at ``estimate`` minutes gets
        when its config names neither ``catch_trials`` nor ``instructed_checks``."""
        return 0

    def idle_limit(self) -> timedelta | None:
        """Return how long a consented participant may go without answering a trial."""
        minutes = self.settings.get("idle_minutes", DEFAULT_IDLE_MINUTES)
        return timedelta(minutes=minutes) if minutes else None

    def warnings(self, estimate: int, checks: int, max_failed: int) -> list[str]:
        """Return what the platform's rules advise against in a study estimated at
        ``estimate`` minutes with ``checks`` attention checks failed after more than
        ``max_failed``."""
        return []

    # Entry

    def normalise(self, name: str, value: str) -> str:
        """Return the platform's spelling of id ``name`` as the link gave it."""
        return value

    def read_ids(self, query) -> tuple[dict, str]:
        """Return ``(ids, key)`` from the entry link's query: the platform parameters
        present, and ``"PARAM:value"`` naming the person ("" when none). Raise
        :class:`EntryRefused` when the link lacks a required id or has a malformed one."""
        ids = {}
        for name in self.id_params + self.extra_params:
            value = _printable(query.get(name, ""))
            if value:
                ids[name] = self.normalise(name, value)
        person = next((name for name in self.id_params if name in ids), "")
        key = f"{person}:{ids[person]}" if person else ""
        if not key and (self.require_id or self.strict_ids):
            raise EntryRefused("no_id", self.id_params[0])
        if self.strict_ids:
            self._check_strict(ids)
        return ids, key

    def _check_strict(self, ids: dict) -> None:
        """Refuse a link whose ids are missing or malformed (``strict_ids``)."""
        person = next(name for name in self.id_params if name in ids)
        for name in (person, *self.extra_params):
            if name not in ids:
                raise EntryRefused("no_id", name)
            if not self.id_format.match(ids[name]):
                raise EntryRefused("bad_id", name)

    def unique_ids(self, ids: dict) -> dict:
        """Return the ids of ``ids`` that no other participant of the study may share."""
        if self.strict_ids and self.session_param in ids:
            return {self.session_param: ids[self.session_param]}
        return {}

    # Exit

    def code_for(self, outcome: str) -> str:
        """Return the completion code of ``outcome``: the study's own; a random one for a
        completed session without one; "" (no code) for any other outcome."""
        from studyapp.survey.models import new_completion_code

        if outcome in self.codes:
            return self.codes[outcome]
        return new_completion_code() if outcome == "completed" else ""

    def completion_url(self, participant) -> str:
        """Return where the last page sends the participant ("" for nowhere): only a
        participant with a code is sent on (a completion URL may credit them)."""
        return participant.study.completion_url if participant.completion_code else ""

    def describe(self) -> dict:
        return {"platform": self.name, "codes": self.codes}


@registry.register("none")
class NoPlatform(Platform):
    pass


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
    COMPLETE = "https://app.prolific.com/submissions/complete?cc={code}"

    def __init__(self, settings):
        super().__init__(settings)
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
        if self.prolific_study_id and ids.get("STUDY_ID") != self.prolific_study_id:
            raise EntryRefused("wrong_study", "STUDY_ID")
        return ids, key

    def completion_url(self, participant):
        code = participant.completion_code
        return self.COMPLETE.format(code=quote(code)) if code else ""


@registry.register("generic")
class Generic(Platform):
    label = "Crowd platform"

    def __init__(self, settings):
        super().__init__(settings)
        param = settings.get("id_param")
        if not isinstance(param, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,49}", param):
            raise ValueError(f"crowd.id_param: {param!r} must name the query parameter that "
                             f"identifies a person, e.g. participantId")
        extra = settings.get("extra_params") or []
        if not isinstance(extra, list) or not all(isinstance(p, str) for p in extra):
            raise ValueError(f"crowd.extra_params: {extra!r} must be a list of parameter names")
        self.id_params = (param,)
        self.extra_params = tuple(extra)
        self.template = settings.get("completion_url_template") or ""
        self.redirects = bool(self.template)
        if self.template and not self.template.startswith(("https://", "http://")):
            raise ValueError(f"crowd.completion_url_template: {self.template!r} must be an "
                             f"http(s) URL with {{code}} (and {{id}}) in it")
        try:
            self.template.format(code="", id="")
        except (KeyError, IndexError, ValueError):
            raise ValueError("crowd.completion_url_template: only {code} and {id} may be "
                             "filled in") from None

    def completion_url(self, participant):
        if not participant.completion_code:
            return ""
        if not self.template:
            return participant.study.completion_url
        person = participant.external_ids.get(self.id_params[0], "")
        return self.template.format(code=quote(participant.completion_code),
                                    id=quote(person))


def platform_of(study) -> Platform:
    """Return the platform adapter of ``study``'s ``crowd`` settings (ValueError if bad)."""
    return make_platform(study.crowd)


def make_platform(settings) -> Platform:
    settings = settings or {}
    if not isinstance(settings, dict):
        raise ValueError(f"crowd: {settings!r} must be a mapping, e.g. {{platform: prolific, "
                         f"codes: {{completed: C1A2B3C4}}}}")
    name = settings.get("platform") or "none"
    try:
        cls = registry.get(name)
    except KeyError:
        raise ValueError(f"crowd.platform: {name!r} is not a platform; choose one of "
                         f"{', '.join(registry.names())}") from None
    return cls(settings)


def list_platforms() -> list[str]:
    return registry.names()
