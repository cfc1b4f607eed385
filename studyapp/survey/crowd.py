"""Crowd platforms: who a participant is, and where they go with which code at the end.

A study's ``crowd`` field names its platform and that platform's settings:

- ``prolific``: the entry link carries ``PROLIFIC_PID`` (24 hex digits, case-insensitive,
  required unless ``require_id: false``), ``STUDY_ID`` and ``SESSION_ID``; each outcome
  has the study's own completion code (``codes``), and the last page sends people to
  ``https://app.prolific.com/submissions/complete?cc=CODE``. ``prolific_study_id`` is
  the id of the study on Prolific (24 hex digits), which ``manage.py prolific create``
  stores and its other subcommands read.
- ``generic``: any other platform (CloudResearch Connect, SONA, a panel of your own):
  ``id_param`` names the query parameter that identifies a person, ``extra_params`` are
  recorded too, ``completion_url_template`` is where people go at the end, with
  ``{code}`` and ``{id}`` filled in.
- no platform (an empty ``crowd``): ``PROLIFIC_PID`` or ``participant_label`` identify a
  person when present; the completion page shows a random code and links to the study's
  ``completion_url``.

Common settings: ``codes`` (``completed``, ``failed_attention``, ``no_consent``,
``screened_out``), ``time_limit_minutes`` (a participant who started longer ago and has
not finished loses their place and can no longer answer, as Prolific times them out),
``screening`` (questions on the consent page; an answer not accepted ends the session
with the ``screened_out`` outcome).
"""

from __future__ import annotations

import re
from urllib.parse import quote

from generation.registry import Registry

OUTCOMES = ("completed", "failed_attention", "no_consent", "screened_out")
SETTINGS = ("platform", "codes", "time_limit_minutes", "id_param", "extra_params",
            "completion_url_template", "require_id", "screening", "prolific_study_id")
MAX_ID_LENGTH = 100
PROLIFIC_ID = re.compile(r"^[0-9a-f]{24}$")

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


class Platform:
    """What a study's crowd platform decides: ids at entry, codes and the way out.

    ``redirects``: the last page sends people on by itself (a platform's own completion
    URL); otherwise it only links to the study's ``completion_url``.
    """

    label = "the study platform"
    redirects = False
    id_params: tuple[str, ...] = ("PROLIFIC_PID", "participant_label")
    extra_params: tuple[str, ...] = ("STUDY_ID", "SESSION_ID")
    require_id = False

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
        bad = sorted(set(codes) - set(OUTCOMES))
        if bad:
            raise ValueError(f"crowd.codes.{bad[0]}: not an outcome; outcomes are "
                             f"{', '.join(OUTCOMES)}")
        for outcome, code in codes.items():
            if not isinstance(code, str) or not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", code):
                raise ValueError(f"crowd.codes.{outcome}: {code!r} must be 1 to 64 letters, "
                                 f"digits, - or _")
        self.codes = dict(codes)
        limit = settings.get("time_limit_minutes")
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int)
                                  or limit < 1):
            raise ValueError(f"crowd.time_limit_minutes: {limit!r} must be a whole number of "
                             f"minutes, at least 1")
        if "require_id" in settings:
            self.require_id = bool(settings["require_id"])
        study_id = settings.get("prolific_study_id")
        if study_id is not None and not (isinstance(study_id, str)
                                         and PROLIFIC_ID.match(study_id.lower())):
            raise ValueError(f"crowd.prolific_study_id: {study_id!r} must be the 24 hex digits "
                             f"of the study's id on Prolific (in its page's address)")
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

    # Entry

    def normalise_id(self, value: str) -> str:
        return value

    def read_ids(self, query) -> tuple[dict, str]:
        """Return ``(ids, key)`` from the entry link's query: the platform parameters
        present, and ``"PARAM:value"`` naming the person ("" when none). Raise
        :class:`EntryRefused` when the link lacks a required id or has a malformed one."""
        ids = {}
        for name in self.id_params + self.extra_params:
            value = _printable(query.get(name, ""))
            if value:
                ids[name] = value
        key = ""
        for name in self.id_params:
            if name in ids:
                ids[name] = self.normalise_id(ids[name])
                key = f"{name}:{ids[name]}"
                break
        if not key and self.require_id:
            raise EntryRefused("no_id", self.id_params[0])
        return ids, key

    # Exit

    def code_for(self, outcome: str) -> str:
        """Return the completion code of ``outcome``: the study's own, else a random one
        for a completed session (or the completed code when only that one is set)."""
        from studyapp.survey.models import new_completion_code

        if outcome in self.codes:
            return self.codes[outcome]
        if outcome in ("completed", "failed_attention"):
            return self.codes.get("completed") or new_completion_code()
        return ""

    def completion_url(self, participant) -> str:
        """Return where the last page sends the participant ("" for nowhere)."""
        return participant.study.completion_url

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
    COMPLETE = "https://app.prolific.com/submissions/complete?cc={code}"

    def __init__(self, settings):
        super().__init__(settings)
        if "completed" not in self.codes:
            raise ValueError("crowd.codes.completed: a Prolific study needs the completion "
                             "code of its 'completed' outcome (from the study's page on "
                             "Prolific, or `manage.py prolific create`)")

    def normalise_id(self, value):
        return value.strip().lower()

    def read_ids(self, query):
        ids, key = super().read_ids(query)
        pid = ids.get("PROLIFIC_PID")
        if pid is not None and not PROLIFIC_ID.match(pid):
            raise EntryRefused("bad_id", "PROLIFIC_PID")
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
        if not self.template:
            return participant.study.completion_url
        person = participant.external_ids.get(self.id_params[0], "")
        return self.template.format(code=quote(participant.completion_code or ""),
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
