"""Per-IP request limits: on the URLs that create participants (entry link, consent), and
on failed logins to the admin.

``STUDY_ENTRY_RATE_LIMIT`` (default ``"120/min"``; ``"N/s"``, ``"N/min"``, ``"N/h"``)
counts requests to the entry link and consent per address, over every study.
``STUDY_ENTRY_RATE_LIMIT_PER_STUDY`` (default ``"60/h"``) counts consents (the posts that
make a participant) per study and address, so one address cannot fill one study's
places. Both count in fixed windows of the period, in Django's cache: per process with
the default local-memory cache, shared by every worker with Redis (``STUDY_CACHE_URL``,
docs/PRODUCTION.md), where the limit is exact. When the cache cannot be reached,
requests are let through (and logged): the limit stops scripts, and an outage of it must
not stop the study.

``STUDY_LOGIN_RATE_LIMIT`` (default ``"10/h"``) counts failed admin logins per address
in the database (:class:`~studyapp.survey.models.FailedLogin`), not the cache: exact
across workers without Redis, and still on while the cache is down. Past it, the login
page answers 429 until the window ends (a success does not reset the window: guessing
stays slow).
"""

import logging
import math
import time
from datetime import datetime, timezone

from django.conf import settings
from django.core.cache import cache
from django.http import HttpResponse

log = logging.getLogger(__name__)

DEFAULT = "120/min"
STUDY_DEFAULT = "60/h"
LOGIN_DEFAULT = "10/h"
PERIODS = {"s": 1, "sec": 1, "min": 60, "m": 60, "h": 3600, "hour": 3600}
LIMITED = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Too many requests</title></head>
<body style="font-family: system-ui, sans-serif; max-width: 36rem; margin: 4rem auto">
<h1>Too many new sessions</h1>
<p>Too many people have started this study from your network just now.
Please wait a minute and open your study link again.</p>
</body></html>
"""


def parse_rate(text: str) -> tuple[float, float]:
    """Return ``(requests, requests per second)`` of ``"120/min"``; raise ValueError."""
    count, _, period = text.strip().partition("/")
    if period not in PERIODS or not count.isdigit() or int(count) < 1:
        raise ValueError(f"rate {text!r}: use N/s, N/min or N/h")
    return float(count), int(count) / PERIODS[period]


def client_ip(request) -> str:
    """The client's address; behind a proxy, the one it appends to X-Forwarded-For."""
    if getattr(settings, "SECURE_PROXY_SSL_HEADER", None):
        forwarded = request.META.get("HTTP_X_FORWARDED_FOR", "")
        if forwarded:
            return forwarded.rsplit(",", 1)[-1].strip()
    return request.META.get("REMOTE_ADDR", "")


def _window(key: str, rate: str, now: float | None) -> tuple[str, float, int]:
    capacity, refill = parse_rate(rate)
    period = capacity / refill
    now = time.time() if now is None else now
    return f"{key}:{int(now // period)}", capacity, int(period) + 60


def window_start(rate: str, now: float | None = None) -> datetime:
    """Return when the current fixed window of ``rate`` began."""
    capacity, refill = parse_rate(rate)
    period = capacity / refill
    now = time.time() if now is None else now
    return datetime.fromtimestamp(now // period * period, tz=timezone.utc)


def allow(key: str, rate: str | None = None, now: float | None = None) -> bool:
    """Count one request against ``key`` in the current window; False past the limit.

    Windows are fixed periods of the rate ("120/min": at most 120 in each clock
    minute). The count is an atomic increment in the cache (Redis INCR; a lock in the
    local-memory cache), so workers sharing a cache never let more through together.
    """
    window, capacity, timeout = _window(
        key, rate or getattr(settings, "STUDY_ENTRY_RATE_LIMIT", DEFAULT), now)
    try:
        cache.add(window, 0, timeout=timeout)
        try:
            count = cache.incr(window)
        except ValueError:  # expired between add and incr
            cache.add(window, 1, timeout=timeout)
            count = 1
    except Exception as error:  # the cache (Redis) is down: fail open
        log.warning("rate limit not applied, the cache is unavailable: %s", error)
        return True
    return count <= capacity


def login_rate() -> str:
    return getattr(settings, "STUDY_LOGIN_RATE_LIMIT", LOGIN_DEFAULT)


def study_rate() -> str:
    return getattr(settings, "STUDY_ENTRY_RATE_LIMIT_PER_STUDY", STUDY_DEFAULT)


def logins_spent(address: str, now: float | None = None) -> bool:
    """Whether ``address`` has used up the failed logins of the current window."""
    from studyapp.survey.models import FailedLogin

    rate = login_rate()
    capacity, _ = parse_rate(rate)
    return FailedLogin.objects.since(address, window_start(rate, now)) >= capacity


def count_failed_login(sender, credentials=None, request=None, **kwargs):
    """Count a failed login against the address it came from (``user_login_failed``)."""
    from studyapp.survey.models import FailedLogin

    if request is not None:
        FailedLogin.objects.record(client_ip(request))


def retry_after(rate: str | None = None, now: float | None = None) -> int:
    """Seconds until the current window of ``rate`` ends."""
    capacity, refill = parse_rate(rate or getattr(settings, "STUDY_ENTRY_RATE_LIMIT", DEFAULT))
    period = capacity / refill
    now = time.time() if now is None else now
    return max(1, math.ceil(period - now % period))


LOGINS = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Too many failed logins</title></head>
<body style="font-family: system-ui, sans-serif; max-width: 36rem; margin: 4rem auto">
<h1>Too many failed logins</h1>
<p>Too many wrong passwords came from your address. Please wait a minute and try again,
or ask another administrator to reset your password.</p>
</body></html>
"""


def too_many(rate: str | None = None, page: str = LIMITED) -> HttpResponse:
    wait = retry_after(rate)
    when = f"{wait} seconds" if wait < 120 else f"{math.ceil(wait / 60)} minutes"
    page = page.replace("Please wait a minute", f"Please wait {when}")
    response = HttpResponse(page, status=429, content_type="text/html; charset=utf-8")
    response["Retry-After"] = str(wait)
    return response


def consents(request) -> bool:
    """Whether ``request`` posts a study's consent page (which makes a participant)."""
    match = request.resolver_match
    return (match is not None and match.view_name == "survey:page"
            and match.kwargs.get("name") == "consent" and request.method == "POST")


def creates_participants(request) -> bool:
    match = request.resolver_match
    if match is None:
        return False
    return match.view_name == "survey:entry" or consents(request)


class EntryRateLimitMiddleware:
    """Apply the entry limits to the entry link and the consent POST, and the login
    limit to the admin's login POST."""

    def __init__(self, get_response):
        self.get_response = get_response

    def __call__(self, request):
        return self.get_response(request)

    def process_view(self, request, view_func, view_args, view_kwargs):
        address = client_ip(request)
        if creates_participants(request) and not allow(f"ratelimit:entry:{address}"):
            return too_many()
        if consents(request):
            slug = request.resolver_match.kwargs.get("slug", "")
            if not allow(f"ratelimit:study:{slug}:{address}", study_rate()):
                return too_many(study_rate())
        match = request.resolver_match
        if (request.method == "POST" and match is not None and match.view_name == "admin:login"
                and logins_spent(address)):
            return too_many(login_rate(), LOGINS)
        return None
