"""Check a posted answer to one trial: the study type's fields for every criterion, the
plays and the page's event log; turn it into an :class:`Answer` to store.

Fields are named ``<prefix>_<item token>`` for the study's first criterion and
``<criterion>.<prefix>_<item token>`` for the others (trial-level answers: ``<name>`` and
``<criterion>.<name>``); a field naming a clip that is not in this trial makes the whole
answer invalid rather than being ignored.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field

from django import forms
from django.core.exceptions import NON_FIELD_ERRORS

MAX_PLAYS = 100_000
MAX_EVENTS = 500
MAX_EVENTS_BYTES = 40_000
MAX_EVENTS_DEPTH = 2  # a list of events, each a list
MAX_NUMBER_DIGITS = 12
EVENTS = ("play", "pause", "seek", "ended", "hidden", "visible", "blur", "focus", "waiting",
          "error", "truncated", "fallback")
# Events that may carry a message as a fourth element: ``fallback`` (the in-page player
# failed and the trial went back to its videos) says why.
WITH_DETAIL = ("fallback",)
MAX_DETAIL_CHARS = 200


@dataclass(frozen=True)
class Criterion:
    """One question asked of a trial's clips: a key for the data and the words shown."""

    key: str
    question: str = ""

    @property
    def text(self) -> str:
        """Return the words shown for this question: its question, else its key as words."""
        return self.question or self.key.replace("_", " ").capitalize()


@dataclass
class Answer:
    """What a checked answer stores: per item and on the trial, per criterion."""

    items: dict = field(default_factory=dict)  # item id -> {criterion: value}
    trial: dict = field(default_factory=dict)  # criterion -> value
    plays: dict = field(default_factory=dict)  # item id -> complete plays reported
    events: list = field(default_factory=list)


def field_name(name: str, criterion_index: int, criterion: Criterion) -> str:
    return name if criterion_index == 0 else f"{criterion.key}.{name}"


def parse_events(text: str) -> list:
    """Return the page's event log, ``[[ms, event, position], ...]``; ValueError if malformed.

    A ``fallback`` event may carry its message as a fourth element (a string of at most
    ``MAX_DETAIL_CHARS`` characters): ``[ms, "fallback", position, message]``.

    The text is bounded before it is parsed: at most ``MAX_EVENTS_BYTES`` of UTF-8, lists
    (or objects) nested at most ``MAX_EVENTS_DEPTH`` deep (Python's JSON parser recurses
    once per level: a tampered post nested thousands deep must not reach it), numbers of
    at most ``MAX_NUMBER_DIGITS`` digits, and no NaN or Infinity.
    """
    if not text:
        return []
    if len(text.encode("utf-8", "surrogatepass")) > MAX_EVENTS_BYTES:
        raise ValueError(f"the event log is longer than {MAX_EVENTS_BYTES} bytes")
    if nesting(text, MAX_EVENTS_DEPTH) > MAX_EVENTS_DEPTH:
        raise ValueError(f"the event log nests deeper than {MAX_EVENTS_DEPTH} levels "
                         "(a list of [milliseconds, name, clip position] events)")
    try:
        events = json.loads(text, parse_int=_short_int, parse_float=_short_float,
                            parse_constant=_no_constant)
    except ValueError as exc:
        if str(exc).startswith("the event log"):
            raise
        raise ValueError("the event log is not JSON") from None
    if not isinstance(events, list) or len(events) > MAX_EVENTS:
        raise ValueError(f"the event log must be a list of at most {MAX_EVENTS} events")
    out = []
    for event in events:
        if not (isinstance(event, list) and len(event) in (3, 4)):
            raise ValueError("each logged event is [milliseconds, name, clip position]")
        ms, name, position = event[:3]
        if isinstance(ms, bool) or not isinstance(ms, int) or not 0 <= ms < 10**9:
            raise ValueError("a logged event has no valid time")
        if name not in EVENTS:
            raise ValueError(f"a logged event is none of {', '.join(EVENTS)}")
        if position is not None and (isinstance(position, bool) or not isinstance(position, int)
                                     or not 0 <= position < 1000):
            raise ValueError("a logged event names no valid clip position")
        if len(event) == 4:
            detail = event[3]
            if name not in WITH_DETAIL:
                raise ValueError(f"a logged event other than {', '.join(WITH_DETAIL)} has "
                                 "no fourth element")
            if not isinstance(detail, str) or len(detail) > MAX_DETAIL_CHARS:
                raise ValueError(f"a logged {name} event's message is not a string of at "
                                 f"most {MAX_DETAIL_CHARS} characters")
            out.append([ms, name, position, detail])
        else:
            out.append([ms, name, position])
    return out


def nesting(text: str, limit: int) -> int:
    """Return how deep the JSON ``text`` nests lists and objects, counting no further than
    ``limit + 1``; brackets inside strings do not count."""
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > limit:
                    break
        elif char in "]}":
            depth -= 1
    return deepest


def _short_int(digits: str) -> int:
    if len(digits.lstrip("-")) > MAX_NUMBER_DIGITS:
        raise ValueError(f"the event log holds a number of more than {MAX_NUMBER_DIGITS} digits")
    return int(digits)


def _short_float(digits: str) -> float:
    if len(digits) > 2 * MAX_NUMBER_DIGITS:
        raise ValueError(f"the event log holds a number of more than {MAX_NUMBER_DIGITS} digits")
    return float(digits)


def _no_constant(name: str):
    raise ValueError(f"the event log holds {name}, which is no number of milliseconds")


class TrialForm(forms.Form):
    """The answer to one trial, with the fields its study type asks for."""

    def __init__(self, study, trial, items, data):
        super().__init__(data)
        self.study, self.trial = study, trial
        self.kind = study.kind
        self.criteria = self.kind.criteria(study)
        self.items = list(items)
        self.judged = [item for item in self.items if item.role == "judged"]
        for item in self.items:
            label = self.label(item)
            self.fields[f"plays_{item.token}"] = forms.IntegerField(
                label=f"Plays of {label.lower()}",
                min_value=1 if item.role == "judged" else 0,
                max_value=MAX_PLAYS,
                error_messages={
                    "required": f"{label} is missing from the answer.",
                    "min_value": f"{label} has not been played to the end yet.",
                },
            )
        self.fields["events"] = forms.CharField(required=False, max_length=MAX_EVENTS_BYTES)
        self.questions = {}
        for index, criterion in enumerate(self.criteria):
            if self.kind.item_prefix:
                for item in self.judged:
                    formfield = self.kind.item_field(study, item, self.label(item),
                                                     len(self.judged))
                    name = field_name(f"{self.kind.item_prefix}_{item.token}", index, criterion)
                    self.fields[name] = self._asked(formfield, criterion, name)
            if self.kind.trial_answer:
                formfield = self.kind.trial_field(study, self.judged)
                name = field_name(self.kind.trial_answer, index, criterion)
                self.fields[name] = self._asked(formfield, criterion, name)

    def _asked(self, formfield, criterion, name):
        if len(self.criteria) > 1:
            # Several questions of the same clips: each field and its errors name theirs.
            formfield.label = f"{criterion.text}: {formfield.label}"
            self.questions[name] = criterion.text
        return formfield

    def label(self, item) -> str:
        """Return the name the participant sees for an item."""
        return self.kind.item_label(item)

    def clean(self):
        tokens = {item.token for item in self.items}
        pattern = re.compile(r"^(?:[a-z0-9_]+\.)?[a-z]+_([A-Za-z0-9_-]+)$")
        for key in self.data:
            match = pattern.match(key)
            if match and key not in self.fields and match.group(1) not in tokens:
                raise forms.ValidationError("The answer names a clip that is not in this question.")
        cleaned = super().clean()
        try:
            cleaned["events"] = parse_events(cleaned.get("events") or "")
        except ValueError as exc:
            raise forms.ValidationError(f"The page's record of playback is malformed: {exc}.")
        for index, criterion in enumerate(self.criteria):
            values = self.item_values(cleaned, index, criterion)
            if None not in values.values():
                problem = self.kind.check_answer(self.study, values, self.judged)
                if problem:
                    several = len(self.criteria) > 1
                    raise forms.ValidationError(f"{criterion.text}: {problem}" if several else problem)
        return cleaned

    def item_values(self, cleaned, index, criterion) -> dict:
        """Return ``{item: cleaned value}`` of one criterion (None where missing)."""
        prefix = self.kind.item_prefix
        if not prefix:
            return {}
        return {
            item: cleaned.get(field_name(f"{prefix}_{item.token}", index, criterion))
            for item in self.judged
        }

    def answer(self) -> Answer:
        """Return the checked answer, ready for ``Trial.objects.record_answer``."""
        cleaned = self.cleaned_data
        answer = Answer(events=cleaned["events"])
        answer.plays = {item.pk: cleaned[f"plays_{item.token}"] for item in self.items}
        for index, criterion in enumerate(self.criteria):
            for item, value in self.item_values(cleaned, index, criterion).items():
                answer.items.setdefault(item.pk, {})[criterion.key] = self.kind.item_value(value)
            if self.kind.trial_answer:
                value = cleaned[field_name(self.kind.trial_answer, index, criterion)]
                answer.trial[criterion.key] = self.kind.trial_value(value, self.judged)
        return answer

    def messages(self) -> list[str]:
        """Return every error as one plain sentence."""
        out = list(self.non_field_errors())
        names = tuple(self.label(item) for item in self.items)
        for name, errors in self.errors.items():
            if name == NON_FIELD_ERRORS:
                continue
            label = self.fields[name].label
            question = self.questions.get(name)
            for e in errors:
                if not e.startswith(names):
                    out.append(f"{label}: {e}")
                elif question:
                    out.append(f"{question}: {e}")
                else:
                    out.append(e)
        return out
