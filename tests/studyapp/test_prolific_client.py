"""The Prolific API client against the local server that follows Prolific's documentation."""

import socket

import pytest

from studyapp.crowd.prolific.client import (
    BadToken,
    Client,
    MissingToken,
    NotFound,
    ProlificError,
    RateLimited,
    Refused,
    Unreachable,
    describe_error,
)
from tests.studyapp.prolific_fake import FakeProlific

TOKEN = "test-token"


@pytest.fixture
def fake():
    with FakeProlific(token=TOKEN) as server:
        yield server


@pytest.fixture
def waits():
    return []


@pytest.fixture
def client(fake, waits):
    return Client(TOKEN, fake.url, sleep=waits.append)


def minimal_study(**fields):
    return {"name": "Movement study", "description": "Watch clips.",
            "external_study_url": "https://study.example/s/x/?PROLIFIC_PID={{%PROLIFIC_PID%}}",
            "prolific_id_option": "url_parameters", "total_available_places": 3,
            "estimated_completion_time": 5, "reward": 100,
            "completion_codes": [{"code": "C1234567", "code_type": "COMPLETED",
                                  "actions": [{"action": "AUTOMATICALLY_APPROVE"}]}], **fields}


def test_the_token_comes_from_prolific_token(monkeypatch, fake):
    monkeypatch.delenv("PROLIFIC_TOKEN", raising=False)
    with pytest.raises(MissingToken, match="PROLIFIC_TOKEN is not set.*API Tokens"):
        Client.from_env()
    monkeypatch.setenv("PROLIFIC_TOKEN", TOKEN)
    monkeypatch.setenv("PROLIFIC_API_URL", fake.url)
    created = Client.from_env().create_study(minimal_study())
    assert fake.requests("POST")[0]["authorization"] == f"Token {TOKEN}"
    assert created["status"] == "UNPUBLISHED" and len(created["id"]) == 24


def test_a_bad_token_says_so_and_how_to_fix_it(fake):
    with pytest.raises(BadToken, match=r"refused the token in PROLIFIC_TOKEN \(401.*export "
                                       r"PROLIFIC_TOKEN="):
        Client("wrong", fake.url).study("0" * 24)


def test_unknown_ids_are_named(client):
    with pytest.raises(NotFound, match=f"no study {'a' * 24} \\(404"):
        client.study("a" * 24)
    with pytest.raises(NotFound, match="no submission nope"):
        client.transition_submission("nope", "APPROVE")


def test_validation_errors_show_prolifics_message(client):
    with pytest.raises(Refused, match="reward: Ensure this value.*greater than or equal to 0"):
        client.create_study(minimal_study(reward=-5))
    bad_code = minimal_study(completion_codes=[
        {"code": "C1", "code_type": "NO_CONSENT", "actions": [{"action": "REQUEST_RETURN"}]}])
    with pytest.raises(Refused, match=r"completion_codes\.0\.actions\.0\.return_reason: This "
                                      r"field is required"):
        client.create_study(bad_code)


def test_429_is_retried_after_retry_after(fake, client, waits):
    study = client.create_study(minimal_study())
    fake.throttle("/studies/", times=2, retry_after="7")
    assert client.study(study["id"])["id"] == study["id"]
    assert waits == [7.0, 7.0]
    assert [r["status"] for r in fake.requests("GET")] == [429, 429, 200]


def test_429_without_retry_after_backs_off_exponentially(fake, client, waits):
    fake.throttle("/studies/", times=3, retry_after=None)
    client.create_study(minimal_study())  # a POST throttled is not processed: safe to resend
    assert waits == [1.0, 2.0, 4.0]
    assert len(fake.studies) == 1


def test_429_that_never_ends_is_a_clear_error(fake, waits):
    fake.throttle("", times=10, retry_after="1")
    with pytest.raises(RateLimited, match="still rate-limiting.*after 2 retries"):
        Client(TOKEN, fake.url, retries=2, sleep=waits.append).study("x")
    assert waits == [1.0, 1.0]


def test_retry_after_is_bounded(client):
    assert client._wait("3600", 0) == client.max_wait
    assert client._wait("Wed, 21 Oct 2015 07:28:00 GMT", 0) == 0.0  # a date in the past
    assert client._wait("soon", 2) == 4.0


def test_network_errors_name_the_address(waits):
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    client = Client(TOKEN, f"http://127.0.0.1:{port}", retries=2, sleep=waits.append)
    with pytest.raises(Unreachable, match=f"Cannot reach Prolific at http://127.0.0.1:{port}/api"):
        client.study("x")
    assert len(waits) == 2  # GETs are retried
    waits.clear()
    with pytest.raises(Unreachable, match="may have received the request"):
        client.pay_bonuses("x")
    assert waits == []  # a POST that may have arrived is never sent twice


def test_pages_are_followed(fake, client):
    study = client.create_study(minimal_study(total_available_places=5))
    client.transition_study(study["id"], "PUBLISH")
    ids = [fake.start(study["id"], f"{k:024x}")[0]["id"] for k in range(5)]
    assert [s["id"] for s in client.study_submissions(study["id"])] == ids
    assert len(fake.requests("GET", "/submissions/")) == 3  # pages of 2


def test_a_next_page_elsewhere_is_not_followed(client):
    with pytest.raises(ProlificError, match="not on http://127.0.0.1.*not following"):
        client._same_site("https://evil.example/api/v1/studies/x/submissions/?offset=2")


def test_the_token_never_travels_unencrypted():
    with pytest.raises(ProlificError, match="unencrypted"):
        Client(TOKEN, "http://api.prolific.example")
    Client(TOKEN, "https://api.prolific.com")  # fine


def test_error_bodies_of_every_documented_shape_are_read():
    assert describe_error(b'{"error": {"title": "Bad", "detail": {"name": ["Required."]}}}') \
        == "name: Required."
    assert describe_error(b'{"error": {"detail": "No.", "additional_information": "See x"}}') \
        == "No.; See x"
    assert describe_error(b'{"message": "Bad request", "detail": "reward too low"}') \
        == "Bad request; reward too low"
    assert describe_error(b'{"reward": ["too low"]}') == "reward: too low"
    assert describe_error(b"<html>Bad gateway</html>") == "<html>Bad gateway</html>"
