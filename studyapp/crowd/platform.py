"""Crowd platforms: who a participant is, and where they go with which code at the end.

A study's ``crowd`` field names its platform and that platform's settings. A platform is
a :class:`Platform` in ``studyapp/crowd/platforms/`` (one module each, registered by
being there: ``none``, ``generic``, ``prolific``), and it decides:

- entry: which query parameters identify a person and are recorded (``id_params``,
  ``extra_params``), how they are read and checked (:meth:`Platform.read_ids`), which
  ids take the study once (:meth:`Platform.unique_ids`), and the link a bot or a test
  opens (:meth:`Platform.entry_params`);
- codes: the completion code of each outcome (:meth:`Platform.code_for`) and which
  outcomes need their own (:meth:`Platform.check_codes`, asked by the build's config
  check and the admin);
- exit: where the last page sends a participant (:meth:`Platform.completion_url`);
- its rules: the default time limit and attention checks, and warnings;
- an API client, when it has an API (:meth:`Platform.client`; None otherwise).

A completion code is only ever the code of the participant's own outcome. A completed
session without its own code gets a random one and any other outcome without its own
code gets none (and no link to the platform's completion URL, which could credit the
person). ``timed_out`` never has a code: platforms time people out themselves, and a
code would let them submit.

Settings every platform has (:data:`SETTINGS`): ``codes`` (``completed``,
``failed_attention``, ``no_consent``, ``screened_out``), ``time_limit_minutes`` (a
participant who consented longer ago and has not finished loses their place and can no
longer answer; ``null``: no limit), ``idle_minutes`` (default 10: a participant who
consented and has not answered a trial for this long loses their place the same way;
``null``: never), ``screening`` (questions on the consent page; an answer not accepted
ends the session with the ``screened_out`` outcome), ``require_id`` and ``strict_ids``
(the platform's ids required, well-formed and, for a session id, unique). A platform adds
its own (``own_settings``).
"""

from __future__ import annotations

import re
import secrets
from datetime import timedelta

from motion.registry import Registry

# Outcomes a completion code can belong to; ``timed_out`` is the one without.
OUTCOMES = ("completed", "failed_attention", "no_consent", "screened_out")
# Settings of every platform; a platform adds its own (Platform.own_settings).
SETTINGS = ("platform", "codes", "time_limit_minutes", "idle_minutes", "require_id",
            "strict_ids", "screening")
MAX_ID_LENGTH = 100
# What a well-formed id of a platform without its own format may hold.
PLAIN_ID = re.compile(r"^[A-Za-z0-9_.:@-]{1,100}$")
DEFAULT_IDLE_MINUTES = 10
registry = Registry("crowd platform", package="studyapp.crowd.platforms")


class EntryRefused(Exception):
    """The entry link cannot start a session; ``reason`` picks the page, ``detail`` says why."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(detail or reason)
        self.reason, self.detail = reason, detail


def _printable(value: str) -> str:
    # Control characters (a NUL byte above all, which PostgreSQL refuses in text) are
    # never part of a platform's ids: drop them rather than fail.
    return "".join(c for c in value if c.isprintable()).strip()[:MAX_ID_LENGTH]


def new_completion_code() -> str:
    """Return a short code a participant pastes into the crowd platform."""
    return secrets.token_hex(4).upper()


def outcomes_of(checks: int, screening: bool) -> list[str]:
    """Return the outcomes with a code a study can end with: ``completed`` and
    ``no_consent`` always, ``failed_attention`` with ``checks`` attention checks,
    ``screened_out`` with screening questions."""
    return [o for o in OUTCOMES if (o != "failed_attention" or checks)
            and (o != "screened_out" or screening)]


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
    id_params: tuple[str, ...] = ()  # query parameters naming a person, the first preferred
    extra_params: tuple[str, ...] = ()  # recorded with them
    own_settings: tuple[str, ...] = ()  # this platform's settings beyond SETTINGS
    require_id = False
    strict_ids = False
    session_param = ""
    id_format = PLAIN_ID
    # What the contract test (and a reader) builds the platform with: its own settings
    # and a person's id as the platform spells it.
    example_settings: dict = {}
    example_person = "P0001"

    def __init__(self, settings: dict):
        settings = dict(settings or {})
        known = SETTINGS + self.own_settings
        unknown = sorted(set(settings) - set(known))
        if unknown:
            raise ValueError(f"crowd.{unknown[0]}: unknown setting; settings are "
                             f"{', '.join(known)}")
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

    def time_limit(self, estimate) -> timedelta | None:
        """Return the study's time limit: ``time_limit_minutes``, else the platform's
        default for a study estimated at ``estimate`` minutes (an int, or a callable
        returning it, called only when a default is needed); None for no limit."""
        if "time_limit_minutes" in self.settings:
            minutes = self.settings["time_limit_minutes"]
        elif type(self).default_time_limit is Platform.default_time_limit:
            minutes = None  # no default limit: the estimate is not needed
        else:
            minutes = self.default_time_limit(estimate() if callable(estimate) else estimate)
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

    def entry_params(self, study, person: str) -> list[tuple[str, str]]:
        """Return the query parameters of an entry link for the person ``person`` (bots
        and tests open it as a platform would send them)."""
        return [(self.id_params[0], person)] if self.id_params else []

    def unique_ids(self, ids: dict) -> dict:
        """Return the ids of ``ids`` that no other participant of the study may share."""
        if self.strict_ids and self.session_param in ids:
            return {self.session_param: ids[self.session_param]}
        return {}

    # Exit

    def code_for(self, outcome: str) -> str:
        """Return the completion code of ``outcome``: the study's own; a random one for a
        completed session without one; "" (no code) for any other outcome."""
        if outcome in self.codes:
            return self.codes[outcome]
        return new_completion_code() if outcome == "completed" else ""

    def completion_url(self, participant) -> str:
        """Return where the last page sends the participant ("" for nowhere): only a
        participant with a code is sent on (a completion URL may credit them)."""
        return participant.study.completion_url if participant.completion_code else ""

    def describe(self) -> dict:
        return {"platform": self.name, "codes": self.codes}

    # API

    def client(self):
        """Return a client of the platform's API, or None for a platform without one."""
        return None

    def stop_recruiting(self, study) -> str:
        """Ask the platform to send no more people to ``study``, which its stopping rule
        closed; return what was done, in words ("" when the platform has nothing to ask)."""
        return ""


def platform_of(study) -> Platform:
    """Return the platform adapter of ``study``'s ``crowd`` settings (ValueError if bad)."""
    return make_platform(study.crowd)


def make_platform(settings) -> Platform:
    settings = settings or {}
    if not isinstance(settings, dict):
        raise ValueError(f"crowd: {settings!r} must be a mapping, e.g. {{platform: generic, "
                         f"id_param: workerId, codes: {{completed: C1A2B3C4}}}}")
    name = settings.get("platform") or "none"
    try:
        cls = registry.get(name)
    except KeyError:
        raise ValueError(f"crowd.platform: {name!r} is not a platform; choose one of "
                         f"{', '.join(registry.names())}") from None
    return cls(settings)


def list_platforms() -> list[str]:
    return registry.names()
