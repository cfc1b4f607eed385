"""A local stand-in for Prolific's REST API, for the tests of ``manage.py prolific``.

It implements the endpoints the command uses as Prolific's API reference documents them
(docs.prolific.com, read in December 2026; see studyapp/crowd/prolific/client.py):
paths, request bodies, validation, status codes, response shapes, pagination by
``_links.next.href`` and errors (401 without the right ``Authorization: Token``, 404 for
unknown ids, 400 with ``{"error": {"detail": ...}}``, 429 with ``Retry-After`` on the
requests a test chooses). It listens on 127.0.0.1 only and stops by itself after
``lifetime`` seconds if a test forgets to.

The participant's side of Prolific is two methods, not HTTP: :meth:`FakeProlific.start`
(someone opens the study on Prolific: a submission starts and they are sent to the
external URL with the placeholders filled in) and :meth:`FakeProlific.arrive` (they come
back through ``https://app.prolific.com/submissions/complete?cc=CODE``: the code's
actions run).
"""

from __future__ import annotations

import json
import math
import re
import secrets
import threading
import urllib.parse
from datetime import datetime, timezone
from decimal import Decimal, InvalidOperation
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

CODE_TYPES = ("COMPLETED", "FAILED_ATTENTION_CHECK", "FOLLOW_UP_STUDY", "GIVE_BONUS",
              "INCOMPATIBLE_DEVICE", "NO_CONSENT", "OTHER", "FIXED_SCREENOUT")
ACTIONS = ("AUTOMATICALLY_APPROVE", "ADD_TO_PARTICIPANT_GROUP",
           "REMOVE_FROM_PARTICIPANT_GROUP", "MANUALLY_REVIEW", "REQUEST_RETURN",
           "DYNAMIC_PAYMENT", "FIXED_SCREEN_OUT_PAYMENT")
ID_OPTIONS = ("question", "url_parameters", "not_required")
REJECTION_CATEGORIES = ("TOO_QUICKLY", "TOO_SLOWLY", "FAILED_INSTRUCTIONS",
                        "INCOMP_LONGITUDINAL", "FAILED_CHECK", "LOW_EFFORT", "MALINGERING",
                        "NO_CODE", "BAD_CODE", "NO_DATA", "UNSUPP_DEVICE", "OTHER")
STUDY_TRANSITIONS = {  # action: (statuses it applies to, the status after)
    "PUBLISH": (("UNPUBLISHED",), "ACTIVE"),
    "PAUSE": (("ACTIVE",), "PAUSED"),
    "START": (("PAUSED",), "ACTIVE"),
    "STOP": (("ACTIVE", "PAUSED"), "AWAITING REVIEW"),
}
COMPLETE_URL = "https://app.prolific.com/submissions/complete"


def new_id() -> str:
    return secrets.token_hex(12)


def now() -> str:
    return datetime.now(timezone.utc).isoformat().replace("+00:00", "Z")


class Answer(Exception):
    """An HTTP answer other than 200, raised from a handler."""

    def __init__(self, status: int, body, headers=None):
        self.status, self.body, self.headers = status, body, headers or {}


def error(status: int, title: str, detail) -> Answer:
    return Answer(status, {"error": {"status": status, "title": title, "detail": detail}})


def refused(detail) -> Answer:
    return error(400, "Bad Request", detail)


class FakeProlific:
    """Prolific's API on ``self.url``; ``token`` is the one valid API token."""

    def __init__(self, token: str = "test-token", page_size: int = 2, lifetime: float = 300):
        self.token, self.page_size = token, page_size
        self.studies: dict[str, dict] = {}
        self.submissions: dict[str, dict] = {}
        self.bulk_bonuses: dict[str, dict] = {}
        self.log: list[dict] = []
        self.throttles: list[dict] = []
        self.lock = threading.RLock()
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):
                fake._serve(self, "GET")

            def do_POST(self):
                fake._serve(self, "POST")

            def do_PATCH(self):
                fake._serve(self, "PATCH")

            def do_DELETE(self):
                fake._serve(self, "DELETE")

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(target=self.server.serve_forever, args=(0.05,), daemon=True)
        self.timer = threading.Timer(lifetime, self.stop)
        self.timer.daemon = True
        self.stopped = False

    # Life

    def start_serving(self) -> "FakeProlific":
        self.thread.start()
        self.timer.start()
        return self

    def stop(self) -> None:
        with self.lock:
            if self.stopped:
                return
            self.stopped = True
        self.timer.cancel()
        self.server.shutdown()
        self.server.server_close()

    def __enter__(self):
        return self.start_serving()

    def __exit__(self, *exc):
        self.stop()

    # What tests set and read

    def throttle(self, match: str = "", times: int = 1, retry_after: str | None = "0") -> None:
        """Answer the next ``times`` requests whose path contains ``match`` with 429
        (``Retry-After: retry_after`` unless None)."""
        with self.lock:
            self.throttles.append({"match": match, "times": times, "retry_after": retry_after})

    def requests(self, method: str = "", path: str = "") -> list[dict]:
        """Return the logged requests (``method``, ``path``, ``body``, ``status``)."""
        return [r for r in self.log if (not method or r["method"] == method)
                and path in r["path"]]

    def start(self, study_id: str, participant_id: str) -> tuple[dict, str]:
        """Someone opens the published study on Prolific: return their new submission and
        the external URL they are sent to (placeholders filled in)."""
        with self.lock:
            study = self.studies[study_id]
            assert study["status"] == "ACTIVE", f"study {study_id} is {study['status']}"
            submission = {"id": new_id(), "study_id": study_id, "participant": participant_id,
                          "status": "ACTIVE", "started_at": now(), "completed_at": None,
                          "study_code": None, "return_requested": None, "bonus_payments": []}
            self.submissions[submission["id"]] = submission
            url = (study["external_study_url"].replace("{{%PROLIFIC_PID%}}", participant_id)
                   .replace("{{%STUDY_ID%}}", study_id)
                   .replace("{{%SESSION_ID%}}", submission["id"]))
            return submission, url

    def arrive(self, participant_id: str, redirect: str) -> dict:
        """The participant comes back through ``redirect`` (Prolific's completion URL):
        record the code they bring and run its actions; return the submission."""
        parts = urllib.parse.urlsplit(redirect)
        assert urllib.parse.urlunsplit(parts[:3] + ("", "")) == COMPLETE_URL, redirect
        code = urllib.parse.parse_qs(parts.query).get("cc", [""])[0]
        with self.lock:
            submission = next(s for s in self.submissions.values()
                              if s["participant"] == participant_id and s["status"] == "ACTIVE")
            study = self.studies[submission["study_id"]]
            submission.update(study_code=code, completed_at=now(), status="AWAITING REVIEW")
            spec = next((c for c in study["completion_codes"] if c["code"] == code), None)
            for action in (spec or {}).get("actions", []):
                if action["action"] == "AUTOMATICALLY_APPROVE":
                    submission["status"] = "APPROVED"
                elif action["action"] == "REQUEST_RETURN":
                    submission["return_requested"] = now()
                elif action["action"] == "FIXED_SCREEN_OUT_PAYMENT":
                    submission["status"] = "SCREENED OUT"
            return submission

    # HTTP

    ROUTES = [
        ("POST", r"/api/v1/studies/", "create_study"),
        ("GET", r"/api/v1/studies/(?P<id>[^/]+)/", "get_study"),
        ("POST", r"/api/v1/studies/(?P<id>[^/]+)/transition/", "transition_study"),
        ("GET", r"/api/v1/studies/(?P<id>[^/]+)/submissions/", "list_submissions"),
        ("POST", r"/api/v1/submissions/bulk-approve/", "bulk_approve"),
        ("POST", r"/api/v1/submissions/bonus-payments/", "set_up_bonuses"),
        ("GET", r"/api/v1/submissions/(?P<id>[^/]+)/", "get_submission"),
        ("POST", r"/api/v1/submissions/(?P<id>[^/]+)/transition/", "transition_submission"),
        ("POST", r"/api/v1/submissions/(?P<id>[^/]+)/request-return/", "request_return"),
        ("POST", r"/api/v1/bulk-bonus-payments/(?P<id>[^/]+)/pay/", "pay_bonuses"),
    ]

    def _serve(self, handler, method: str) -> None:
        parts = urllib.parse.urlsplit(handler.path)
        path = parts.path if parts.path.endswith("/") else parts.path + "/"
        length = int(handler.headers.get("Content-Length") or 0)
        raw = handler.rfile.read(length) if length else b""
        entry = {"method": method, "path": parts.path, "query": parts.query, "body": None,
                 "authorization": handler.headers.get("Authorization", "")}
        try:
            self._throttled(path)
            if handler.headers.get("Authorization") != f"Token {self.token}":
                raise error(401, "Unauthorized", "Invalid token.")
            body = json.loads(raw) if raw else {}
            entry["body"] = body
            status, answer = self._route(method, path, parts.query, body)
            headers = {}
        except Answer as answer_:
            status, answer, headers = answer_.status, answer_.body, answer_.headers
        except ValueError:
            status, answer, headers = 400, {"error": {"status": 400, "title": "Bad Request",
                                                      "detail": "JSON parse error"}}, {}
        entry["status"] = status
        with self.lock:
            self.log.append(entry)
        data = json.dumps(answer).encode()
        handler.send_response(status)
        handler.send_header("Content-Type", "application/json")
        handler.send_header("Content-Length", str(len(data)))
        for name, value in headers.items():
            handler.send_header(name, value)
        handler.end_headers()
        handler.wfile.write(data)

    def _throttled(self, path: str) -> None:
        with self.lock:
            for rule in self.throttles:
                if rule["times"] > 0 and rule["match"] in path:
                    rule["times"] -= 1
                    headers = {} if rule["retry_after"] is None else {
                        "Retry-After": rule["retry_after"]}
                    raise Answer(429, {"error": {"status": 429, "title": "Too Many Requests",
                                                 "detail": "Request was throttled."}}, headers)

    def _route(self, method: str, path: str, query: str, body):
        known = False
        for verb, pattern, name in self.ROUTES:
            match = re.fullmatch(pattern, path)
            if match:
                known = True
                if verb == method:
                    with self.lock:
                        return getattr(self, name)(body, query=query, **match.groupdict())
        if known:
            raise error(405, "Method Not Allowed", f'Method "{method}" not allowed.')
        raise error(404, "Not Found", "Not found.")

    def _study(self, study_id: str) -> dict:
        if study_id not in self.studies:
            raise error(404, "Not Found", "Not found.")
        return self.studies[study_id]

    def _submission(self, submission_id: str) -> dict:
        if submission_id not in self.submissions:
            raise error(404, "Not Found", "Not found.")
        return self.submissions[submission_id]

    # Studies

    def create_study(self, body, query=""):
        problems = self._check_study(body)
        if problems:
            raise refused(problems)
        study = {**body, "id": new_id(), "status": "UNPUBLISHED", "date_created": now(),
                 "places_taken": 0, "published_at": None}
        self.studies[study["id"]] = study
        return 201, study

    def _check_study(self, body) -> dict:
        problems: dict[str, list[str]] = {}

        def problem(field, message):
            problems.setdefault(field, []).append(message)

        if not isinstance(body, dict):
            return {"non_field_errors": ["Expected an object."]}
        for field in ("name", "description", "prolific_id_option", "completion_codes",
                      "total_available_places", "estimated_completion_time", "reward"):
            if body.get(field) in (None, "", []):
                problem(field, "This field is required.")
        if not body.get("external_study_url") and not body.get("access_details"):
            problem("external_study_url", "This field is required.")
        option = body.get("prolific_id_option")
        if option and option not in ID_OPTIONS:
            problem("prolific_id_option", f'"{option}" is not a valid choice.')
        url = body.get("external_study_url") or ""
        if url and not url.startswith(("http://", "https://")):
            problem("external_study_url", "Enter a valid URL.")
        if option == "url_parameters" and url and "{{%PROLIFIC_PID%}}" not in url:
            problem("external_study_url", "The URL must include {{%PROLIFIC_PID%}} when the "
                                          "Prolific ID is passed as URL parameters.")
        for field, least in (("total_available_places", 1), ("estimated_completion_time", 1),
                             ("reward", 0)):
            value = body.get(field)
            if value is not None and (not isinstance(value, (int, float))
                                      or isinstance(value, bool) or value < least):
                problem(field, f"Ensure this value is a number greater than or equal to {least}.")
        limit = body.get("maximum_allowed_time")
        estimate = body.get("estimated_completion_time") or 0
        least = math.ceil(2 + estimate + 2 * math.sqrt(estimate)) if isinstance(
            estimate, (int, float)) and estimate > 0 else 0
        if limit is not None and (not isinstance(limit, int) or limit < least):
            # Prolific's help centre: the least maximum time is 2 + X + 2 sqrt(X) for an
            # estimated completion time of X minutes.
            problem("maximum_allowed_time", f"Must be at least {least} minutes for this "
                                            f"estimated completion time.")
        codes = body.get("completion_codes") or []
        if not isinstance(codes, list):
            problem("completion_codes", "Expected a list.")
            codes = []
        seen = set()
        for i, spec in enumerate(codes):
            where = f"completion_codes.{i}"
            if not isinstance(spec, dict):
                problem(where, "Expected an object.")
                continue
            code = spec.get("code")
            if not isinstance(code, str) or not code:
                problem(f"{where}.code", "This field is required.")
            elif code in seen:
                problem(f"{where}.code", "Each code must be unique within a study.")
            seen.add(code)
            if spec.get("code_type") not in CODE_TYPES:
                problem(f"{where}.code_type", f'"{spec.get("code_type")}" is not a valid choice.')
            if spec.get("actor", "participant") not in ("participant", "researcher"):
                problem(f"{where}.actor", f'"{spec.get("actor")}" is not a valid choice.')
            names = [a.get("action") if isinstance(a, dict) else None
                     for a in spec.get("actions") or []]
            for j, action in enumerate(spec.get("actions") or []):
                name = names[j]
                if name not in ACTIONS:
                    problem(f"{where}.actions.{j}.action", f'"{name}" is not a valid choice.')
                elif name == "REQUEST_RETURN" and not action.get("return_reason"):
                    problem(f"{where}.actions.{j}.return_reason", "This field is required.")
                elif name == "FIXED_SCREEN_OUT_PAYMENT":
                    reward = action.get("fixed_screen_out_reward")
                    if not isinstance(reward, int) or not 0 < reward < (body.get("reward") or 0):
                        problem(f"{where}.actions.{j}.fixed_screen_out_reward",
                                "Must be more than 0 and less than the study's reward.")
                    if not isinstance(action.get("slots"), int) or action["slots"] < 1:
                        problem(f"{where}.actions.{j}.slots", "This field is required.")
                elif name in ("ADD_TO_PARTICIPANT_GROUP", "REMOVE_FROM_PARTICIPANT_GROUP") \
                        and not action.get("participant_group"):
                    problem(f"{where}.actions.{j}.participant_group", "This field is required.")
            if "AUTOMATICALLY_APPROVE" in names and "MANUALLY_REVIEW" in names:
                problem(f"{where}.actions", "AUTOMATICALLY_APPROVE and MANUALLY_REVIEW cannot "
                                            "be used together.")
        return problems

    def get_study(self, body, id, query=""):
        return 200, self._study(id)

    def transition_study(self, body, id, query=""):
        study = self._study(id)
        action = (body or {}).get("action")
        if action not in STUDY_TRANSITIONS:
            raise refused({"action": [f'"{action}" is not a valid choice.']})
        before, after = STUDY_TRANSITIONS[action]
        if study["status"] not in before:
            raise refused(f"Cannot {action.lower()} a study that is {study['status']}.")
        study["status"] = after
        if action == "PUBLISH":
            study["published_at"] = now()
        return 200, study

    def list_submissions(self, body, id, query=""):
        self._study(id)
        params = urllib.parse.parse_qs(query)
        limit = int(params.get("limit", [self.page_size])[0])
        offset = int(params.get("offset", [0])[0])
        mine = sorted((s for s in self.submissions.values() if s["study_id"] == id),
                      key=lambda s: s["started_at"])
        page = mine[offset:offset + limit]
        base = f"{self.url}/api/v1/studies/{id}/submissions/"

        def link(start):
            return f"{base}?limit={limit}&offset={start}"

        results = [{"id": s["id"], "participant_id": s["participant"], "status": s["status"],
                    "started_at": s["started_at"], "completed_at": s["completed_at"],
                    "has_siblings": False, "study_code": s["study_code"],
                    "return_requested": s["return_requested"]} for s in page]
        more = offset + limit < len(mine)
        return 200, {
            "results": results,
            "_links": {"self": {"href": link(offset), "title": "Current page"},
                       "next": {"href": link(offset + limit) if more else None,
                                "title": "Next page"},
                       "previous": {"href": link(max(0, offset - limit)) if offset else None,
                                    "title": "Previous page"},
                       "last": {"href": link(max(0, (len(mine) - 1) // limit * limit)),
                                "title": "Last page"}},
            "meta": {"count": len(mine)},
        }

    # Submissions

    def _short(self, s):
        return {"id": s["id"], "started_at": s["started_at"], "status": s["status"],
                "study_id": s["study_id"], "completed_at": s["completed_at"],
                "entered_code": s["study_code"], "participant": s["participant"]}

    def get_submission(self, body, id, query=""):
        s = self._submission(id)
        return 200, {**self._short(s), "bonus_payments": list(s["bonus_payments"]),
                     "return_requested": s["return_requested"]}

    def transition_submission(self, body, id, query=""):
        s = self._submission(id)
        action = (body or {}).get("action")
        target = {"APPROVE": "APPROVED", "REJECT": "REJECTED"}.get(action)
        if target is None:
            raise refused({"action": [f'"{action}" is not a valid choice.']})
        if s["status"] == target:
            return 200, self._short(s)  # documented as idempotent: the repeat is ignored
        if action == "REJECT":
            problems = {}
            if len((body or {}).get("message") or "") < 100:
                problems["message"] = ["Ensure this field has at least 100 characters."]
            if (body or {}).get("rejection_category") not in REJECTION_CATEGORIES:
                problems["rejection_category"] = ["This field is required."]
            if problems:
                raise refused(problems)
        if s["status"] != "AWAITING REVIEW":
            raise refused(f"The submission is {s['status']}; only submissions awaiting review "
                          f"can be {target.lower()}.")
        s["status"] = target
        return 200, self._short(s)

    def request_return(self, body, id, query=""):
        s = self._submission(id)
        reasons = (body or {}).get("request_return_reasons")
        if not isinstance(reasons, list) or not reasons or not all(
                isinstance(r, str) and r for r in reasons):
            raise refused({"request_return_reasons": ["This field is required."]})
        if s["status"] not in ("AWAITING REVIEW", "ACTIVE"):
            raise refused(f"Cannot request a return of a submission that is {s['status']}.")
        s["return_requested"] = s["return_requested"] or now()
        return 200, {"id": s["id"], "status": s["status"], "participant": s["participant"],
                     "return_requested": s["return_requested"]}

    def bulk_approve(self, body, query=""):
        body = body or {}
        if "submission_ids" in body:
            chosen = [self.submissions.get(i) for i in body["submission_ids"]]
            unknown = [i for i, s in zip(body["submission_ids"], chosen) if s is None]
        elif "study_id" in body and "participant_ids" in body:
            self._study(body["study_id"])
            by_pid = {s["participant"]: s for s in self.submissions.values()
                      if s["study_id"] == body["study_id"]}
            chosen = [by_pid.get(p) for p in body["participant_ids"]]
            unknown = [p for p, s in zip(body["participant_ids"], chosen) if s is None]
        else:
            raise refused("Provide submission_ids, or study_id and participant_ids.")
        if unknown:
            raise refused(f"Unknown ids: {', '.join(unknown)}")
        wrong = [s["id"] for s in chosen if s["status"] not in ("AWAITING REVIEW", "APPROVED")]
        if wrong:
            raise refused(f"Only submissions awaiting review can be approved: {', '.join(wrong)}")
        for s in chosen:
            s["status"] = "APPROVED"
        return 200, "The request to bulk approve is being handled."

    # Bonuses

    def set_up_bonuses(self, body, query=""):
        body = body or {}
        study = self._study(body.get("study_id", ""))
        mine = {s["participant"]: s for s in self.submissions.values()
                if s["study_id"] == study["id"]}
        mine.update({s["id"]: s for s in list(mine.values())})
        lines, bad = [], []
        for line in str(body.get("csv_bonuses") or "").splitlines():
            if not line.strip():
                continue
            who, _, amount = line.partition(",")
            try:
                cents = int(Decimal(amount.strip()) * 100)
            except InvalidOperation:
                bad.append(f"{line!r}: not an amount")
                continue
            if who.strip() not in mine:
                bad.append(f"{who.strip()}: did not take part in this study")
                continue
            lines.append((mine[who.strip()]["id"], cents))
        if bad or not lines:
            raise refused({"csv_bonuses": bad or ["This field is required."]})
        amount = sum(c for _, c in lines)
        fees = round(amount / 3, 2)
        bulk = {"id": new_id(), "study": study["id"], "amount": amount, "fees": fees,
                "vat": 0, "total_amount": round(amount + fees, 2), "lines": lines, "paid": 0}
        self.bulk_bonuses[bulk["id"]] = bulk
        return 201, {k: bulk[k] for k in ("id", "study", "amount", "fees", "vat",
                                          "total_amount")}

    def pay_bonuses(self, body, id, query=""):
        if id not in self.bulk_bonuses:
            raise error(404, "Not Found", "Not found.")
        bulk = self.bulk_bonuses[id]
        bulk["paid"] += 1  # not idempotent, as documented: paying twice pays twice
        for submission_id, cents in bulk["lines"]:
            self.submissions[submission_id]["bonus_payments"].append(cents)
        return 202, (f"Bulk bonus payment with ID {id} is being processed asynchronously. "
                     f"Payments will be completed shortly.")
