"""The page's event log is bounded before it is parsed: a tampered one is a 400, never a 500.

Before the bound, an ``events`` field nested 3,000 deep made Python's JSON parser
recurse past its limit: a RecursionError, a 500 (and, in the demo, Django's debug page).
"""

import json
import os

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from studyapp.participation.answers import MAX_EVENTS_BYTES, nesting, parse_events

pytestmark = pytest.mark.django_db
FUZZ = settings(max_examples=int(os.environ.get("STUDY_FUZZ_EXAMPLES", "50")), deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture
def joined(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="events")
    bot.trial_page()  # shown and its clips fetched: only the answer is left to check
    return bot


def answered(study) -> int:
    from studyapp.survey.models import Trial

    return Trial.objects.filter(participant__study=study, answered_at__isnull=False).count()


def post_events(bot, events: str):
    trial = bot.participant().current_trial()
    return bot.answer({**bot.answer_data(trial), "events": events})


TAMPERED = {
    "lists 3,000 deep": ("[" * 3000 + "]" * 3000, "nests deeper than 2 levels"),
    "objects 3,000 deep": ('{"a":' * 3000 + "1" + "}" * 3000, "nests deeper than 2 levels"),
    "a list 3 deep": ('[[[0, "play", 0]]]', "nests deeper than 2 levels"),
    "a 5,000-digit number": ("[[" + "9" * 5000 + ', "play", 0]]', "more than 12 digits"),
    "a 13-digit number": ('[[1234567890123, "play", 0]]', "more than 12 digits"),
    "an overflowing float": ('[[1e999, "play", 0]]', "no valid time"),
    "NaN": ('[[NaN, "play", 0]]', "holds NaN"),
    "a long string": ('[[0, "' + "x" * 39_000 + '", 0]]', "none of play"),
    "40,000 characters of 4 bytes": ('[[0, "' + "\U0001f600" * 10_000 + '", 0]]',
                                     f"longer than {MAX_EVENTS_BYTES} bytes"),
    "brackets in a string do not count": ('[[0, "[[[[[[", 0]]', "none of play"),
}


@pytest.mark.parametrize("case", TAMPERED)
def test_tampered_event_logs_are_refused_with_a_clear_message(joined, case):
    events, words = TAMPERED[case]
    response = post_events(joined, events)
    assert response.status_code == 400
    page = response.content.decode()
    assert "record of playback is malformed" in page and words in page, page[-3000:]
    assert answered(joined.study) == 0


def test_a_well_formed_log_still_goes_through(joined):
    response = post_events(joined, json.dumps([[0, "play", 0], [1200, "ended", 0],
                                               [1300, "play", None]]))
    assert response.status_code == 302
    assert answered(joined.study) == 1


JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                    lambda inner: st.lists(inner, max_size=4)
                    | st.dictionaries(st.text(max_size=4), inner, max_size=4), max_leaves=30)


@FUZZ
@given(value=JSON, depth=st.integers(0, 4000))
def test_any_json_at_any_depth_is_parsed_or_refused_never_an_error(value, depth):
    text = "[" * depth + json.dumps(value) + "]" * depth
    try:
        events = parse_events(text)
    except ValueError as exc:
        assert str(exc).startswith("the event log") or "logged event" in str(exc)
    else:
        assert isinstance(events, list) and nesting(text, 2) <= 2


def test_a_fallback_carries_its_message_and_nothing_else_does():
    logged = [[0, "fallback", 1, "Error: HTTP 404"], [900, "ended", 0]]
    assert parse_events(json.dumps(logged)) == logged
    assert parse_events(json.dumps([[0, "fallback", None, "WebGL context lost"]]))
    for bad, words in [([[0, "ended", 0, "why"]], "no fourth element"),
                       ([[0, "fallback", 0, 404]], "message is not a string"),
                       ([[0, "fallback", 0, "x" * 201]], "at most 200 characters"),
                       ([[0, "fallback", 0, "a", "b"]], "each logged event")]:
        with pytest.raises(ValueError, match=words):
            parse_events(json.dumps(bad))
