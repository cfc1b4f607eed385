"""A small client of Prolific's REST API (v1), on the standard library only.

Written from Prolific's published API reference (https://docs.prolific.com, API
Reference, as read in December 2026): "API Fundamentals" (the ``Authorization: Token
<token>`` header; error codes 400, 401, 404, 405, 422, 429), "Managing high loads"
(429 Too Many Requests is transient: retry with back-off), "Create a draft study"
(``POST /api/v1/studies/``, 201), "The study object", "Retrieve a study", "Transition a
study's status" (``POST /api/v1/studies/{id}/transition/``: ``PUBLISH``, ``PAUSE``,
``START``, ``STOP``), "List study submissions" (``GET /api/v1/studies/{id}/submissions/``:
``results`` with ``_links.next.href`` to the next page and ``meta.count``), "Retrieve a
submission" (``GET /api/v1/submissions/{id}/``), "Approve or reject a submission"
(``POST /api/v1/submissions/{id}/transition/``; a rejection needs a message of at
least 100 characters and a ``rejection_category``; idempotent), "Request the
participant ... to return" (``POST /api/v1/submissions/{id}/request-return/`` with
``request_return_reasons``), "Bulk approve submissions" (``POST
/api/v1/submissions/bulk-approve/`` with ``submission_ids``), "Set up bonuses" (``POST
/api/v1/submissions/bonus-payments/``: ``study_id`` and ``csv_bonuses`` lines
``<participant_id>,<amount>`` in the study's currency, e.g. ``4.25``; 201 with the
bulk payment's ``id``, ``amount``, ``fees``, ``total_amount``) and "Pay bonuses" (``POST
/api/v1/bulk-bonus-payments/{id}/pay/``, 202, paid asynchronously and *not*
idempotent). Error bodies come in the shapes Prolific's own CLI (prolific-oss/cli)
reads: ``{"error": {"title", "detail", "additional_information"}}`` (``detail`` a text,
a list or ``{field: [messages]}``) or ``{"message", "detail"}``.

Requests that fail with 429 are retried, waiting as long as ``Retry-After`` says (seconds
or an HTTP date) or, without it, 1, 2, 4, ... seconds. Only GET requests are retried
after a network error or a 5xx answer: a POST that may have reached Prolific (a bonus
payment above all) is never sent twice.
"""

from __future__ import annotations

import email.utils
import json
import os
import socket
import time
import urllib.error
import urllib.parse
import urllib.request
from datetime import datetime, timezone

API_URL = "https://api.prolific.com"
TOKEN_VARIABLE = "PROLIFIC_TOKEN"
URL_VARIABLE = "PROLIFIC_API_URL"
TOKEN_HELP = (f"create a token on Prolific (the API Tokens page of your account's "
              f"settings), then `export {TOKEN_VARIABLE}=<token>`")
LOOPBACK = ("127.0.0.1", "localhost", "::1")
MAX_PAGES = 10_000


class ProlificError(Exception):
    """A request to Prolific failed; the message says what was asked, what came back and
    what to do. ``status`` is the HTTP status (None when nothing came back)."""

    def __init__(self, message: str, status: int | None = None):
        super().__init__(message)
        self.status = status


class MissingToken(ProlificError):
    pass


class BadToken(ProlificError):
    """401: the token is wrong or was deleted."""


class NotFound(ProlificError):
    """404: no such study, submission or bulk payment."""


class Refused(ProlificError):
    """400 or 422: Prolific's own validation message is in the text."""


class RateLimited(ProlificError):
    """429, still, after every retry."""


class Unreachable(ProlificError):
    """No answer: DNS, refused connection, timeout."""


def _path_id(value: str) -> str:
    return urllib.parse.quote(str(value), safe="")


def describe_error(body: bytes) -> str:
    """Return the message of a Prolific error body in one line (its text when not JSON)."""
    text = body.decode("utf-8", errors="replace").strip()
    try:
        data = json.loads(text)
    except ValueError:
        return text[:300]
    if isinstance(data, dict) and isinstance(data.get("error"), dict):
        error = data["error"]
        parts = [_flatten(error.get("detail")) or str(error.get("title") or "")]
        extra = error.get("additional_information")
        if extra:
            parts.append(str(extra))
        return "; ".join(p for p in parts if p) or text[:300]
    if isinstance(data, dict) and ("message" in data or "detail" in data):
        return "; ".join(p for p in (_flatten(data.get("message")),
                                     _flatten(data.get("detail"))) if p)
    return _flatten(data) or text[:300]


def _flatten(detail, prefix: str = "") -> str:
    """Turn ``{"field": ["message"]}``, lists and texts into ``field: message; ...``."""
    if detail is None or detail == "":
        return ""
    if isinstance(detail, dict):
        return "; ".join(_flatten(value, f"{prefix}{key}.") for key, value in detail.items())
    if isinstance(detail, list):
        return "; ".join(_flatten(value, prefix) for value in detail)
    label = prefix.rstrip(".")
    return f"{label}: {detail}" if label else str(detail)


class Client:
    """Prolific's API with one token. Methods return the decoded JSON of the answer.

    ``sleep`` is how the client waits before a retry (tests pass a recorder).
    """

    def __init__(self, token: str, base_url: str = API_URL, retries: int = 5,
                 max_wait: float = 60.0, timeout: float = 30.0, sleep=time.sleep):
        if not token:
            raise MissingToken(f"{TOKEN_VARIABLE} is not set: {TOKEN_HELP}")
        base_url = (base_url or API_URL).rstrip("/")
        parts = urllib.parse.urlsplit(base_url)
        if parts.scheme not in ("http", "https") or not parts.netloc:
            raise ProlificError(f"{URL_VARIABLE}={base_url!r} must be an http(s) address "
                                f"such as {API_URL}")
        if parts.scheme == "http" and parts.hostname not in LOOPBACK:
            raise ProlificError(f"{URL_VARIABLE}={base_url!r}: the token would travel "
                                f"unencrypted; use https (or a server on this machine)")
        self.token, self.base_url = token, base_url
        self.retries, self.max_wait, self.timeout, self.sleep = retries, max_wait, timeout, sleep

    @classmethod
    def from_env(cls, **options) -> "Client":
        """Return a client with the token of ``PROLIFIC_TOKEN`` (and ``PROLIFIC_API_URL``)."""
        return cls(os.environ.get(TOKEN_VARIABLE, "").strip(),
                   os.environ.get(URL_VARIABLE, "").strip() or API_URL, **options)

    # Studies

    def create_study(self, payload: dict) -> dict:
        return self.call("POST", "/api/v1/studies/", payload, what="a draft study")

    def study(self, study_id: str) -> dict:
        return self.call("GET", f"/api/v1/studies/{_path_id(study_id)}/",
                         what=f"study {study_id}")

    def transition_study(self, study_id: str, action: str) -> dict:
        return self.call("POST", f"/api/v1/studies/{_path_id(study_id)}/transition/",
                         {"action": action}, what=f"study {study_id}")

    def study_submissions(self, study_id: str) -> list[dict]:
        """Return every submission of a study, following the pages' ``next`` links."""
        return list(self.pages(f"/api/v1/studies/{_path_id(study_id)}/submissions/",
                               what=f"the submissions of study {study_id}"))

    # Submissions

    def submission(self, submission_id: str) -> dict:
        return self.call("GET", f"/api/v1/submissions/{_path_id(submission_id)}/",
                         what=f"submission {submission_id}")

    def transition_submission(self, submission_id: str, action: str, **fields) -> dict:
        body = {"action": action, **{k: v for k, v in fields.items() if v is not None}}
        return self.call("POST", f"/api/v1/submissions/{_path_id(submission_id)}/transition/",
                         body, what=f"submission {submission_id}")

    def request_return(self, submission_id: str, reasons: list[str]) -> dict:
        return self.call("POST",
                         f"/api/v1/submissions/{_path_id(submission_id)}/request-return/",
                         {"request_return_reasons": list(reasons)},
                         what=f"submission {submission_id}")

    def bulk_approve(self, submission_ids: list[str]):
        return self.call("POST", "/api/v1/submissions/bulk-approve/",
                         {"submission_ids": list(submission_ids)},
                         what=f"{len(submission_ids)} submission(s) to approve")

    # Bonuses

    def set_up_bonuses(self, study_id: str, csv_bonuses: str) -> dict:
        return self.call("POST", "/api/v1/submissions/bonus-payments/",
                         {"study_id": study_id, "csv_bonuses": csv_bonuses},
                         what=f"bonuses of study {study_id}")

    def pay_bonuses(self, bulk_id: str):
        return self.call("POST", f"/api/v1/bulk-bonus-payments/{_path_id(bulk_id)}/pay/", {},
                         what=f"bulk bonus payment {bulk_id}")

    # Transport

    def pages(self, path: str, what: str):
        """Yield the ``results`` of every page from ``path`` on."""
        url, seen = path, set()
        for _ in range(MAX_PAGES):
            page = self.call("GET", url, what=what)
            yield from (page or {}).get("results") or []
            link = (((page or {}).get("_links") or {}).get("next") or {}).get("href")
            if not link:
                return
            url = self._same_site(link)
            if url in seen:
                raise ProlificError(f"Prolific's pages of {what} loop back to {url}")
            seen.add(url)
        raise ProlificError(f"{what}: more than {MAX_PAGES} pages")

    def _same_site(self, link: str) -> str:
        """Return ``link`` made absolute; refuse one to another site (it would get the token)."""
        url = urllib.parse.urljoin(self.base_url + "/", link)
        ours, theirs = urllib.parse.urlsplit(self.base_url), urllib.parse.urlsplit(url)
        if (theirs.scheme, theirs.netloc) != (ours.scheme, ours.netloc):
            raise ProlificError(f"Prolific's next page {link!r} is not on {self.base_url}; "
                                f"not following it (the token would go there)")
        return url

    def call(self, method: str, path: str, body=None, what: str = ""):
        """Send one request (retrying as the module docstring says); return its JSON."""
        url = path if path.startswith(("http://", "https://")) else self.base_url + path
        data = None if body is None else json.dumps(body).encode()
        headers = {"Authorization": f"Token {self.token}", "Accept": "application/json",
                   "User-Agent": "motion-study-prolific/1"}
        if data is not None:
            headers["Content-Type"] = "application/json"
        for attempt in range(self.retries + 1):
            request = urllib.request.Request(url, data=data, method=method, headers=headers)
            last = attempt == self.retries
            try:
                with urllib.request.urlopen(request, timeout=self.timeout) as response:
                    raw = response.read()
                break
            except urllib.error.HTTPError as error:
                raw = error.read()
                if error.code == 429 and not last:
                    self.sleep(self._wait(error.headers.get("Retry-After"), attempt))
                    continue
                if error.code >= 500 and method == "GET" and not last:
                    self.sleep(self._wait(None, attempt))
                    continue
                raise self._error(error.code, raw, method, url, what) from None
            except (urllib.error.URLError, socket.timeout, ConnectionError) as error:
                if method == "GET" and not last:
                    self.sleep(self._wait(None, attempt))
                    continue
                reason = getattr(error, "reason", error)
                sent = "" if method == "GET" else (
                    " Prolific may have received the request: check with `manage.py prolific "
                    "submissions` before sending it again.")
                raise Unreachable(f"Cannot reach Prolific at {url} ({reason}); check the "
                                  f"network and {URL_VARIABLE}.{sent}") from None
        try:
            return json.loads(raw) if raw.strip() else None
        except ValueError:
            raise ProlificError(f"Prolific's answer to {method} {url} is not JSON: "
                                f"{raw[:200]!r}") from None

    def _wait(self, retry_after: str | None, attempt: int) -> float:
        """Return the seconds to wait: ``Retry-After`` (seconds or a date), else 2**attempt."""
        seconds = None
        if retry_after:
            try:
                seconds = float(retry_after)
            except ValueError:
                try:
                    when = email.utils.parsedate_to_datetime(retry_after)
                    seconds = (when - datetime.now(timezone.utc)).total_seconds()
                except (TypeError, ValueError):
                    seconds = None
        if seconds is None:
            seconds = 2.0 ** attempt
        return min(max(seconds, 0.0), self.max_wait)

    def _error(self, status: int, raw: bytes, method: str, url: str, what: str):
        said = describe_error(raw)
        asked = what or f"{method} {url}"
        if status == 401:
            return BadToken(f"Prolific refused the token in {TOKEN_VARIABLE} (401 "
                            f"Unauthorized: {said or 'no valid token'}). It is mistyped or was "
                            f"deleted: {TOKEN_HELP}.", status)
        if status == 404:
            return NotFound(f"Prolific has no {asked} (404 Not Found); check the id.", status)
        if status in (400, 422):
            return Refused(f"Prolific refused {asked} ({status}): {said}", status)
        if status == 429:
            return RateLimited(f"Prolific is still rate-limiting requests for {asked} after "
                               f"{self.retries} retries (429 Too Many Requests); try again in "
                               f"a few minutes.", status)
        return ProlificError(f"Prolific answered {status} to {asked}: {said}", status)
