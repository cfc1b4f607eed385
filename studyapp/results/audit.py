"""Run the blindness audit (:mod:`analysis.blindness`) on a built study, through HTTP.

The audit shows every clip of the study to temporary audit participants (a practice
trial each, so no balance count changes; never consented, so they hold no place) and
fetches each clip's files (video, poster, payload) under their item tokens, exactly as a
participant's browser would, from the server at ``url`` (or in-process from the clip
view, as ``analyze`` does). The basic level shows each clip once and tests what a
browser receives; the deep level shows each clip ``DELIVERIES`` times (as a repeated
trial and other participants would see it) and also tests what a script parses out of
the files. The audit participants are deleted afterwards.
"""

from __future__ import annotations

import secrets
import urllib.error
import urllib.request

from django.db import transaction

from analysis.blindness import ClipRecord, assess, passed  # noqa: F401 (passed: for callers)
from studyapp.stimuli import media
from studyapp.survey.models import Participant, Stimulus, Trial, TrialItem

AUDIT_KEY = "audit:blindness"
TIMEOUT = 30
DELIVERIES = 2  # deliveries of every clip at the deep level
LEVELS = ("deep", "basic")


class AuditUnavailable(RuntimeError):
    """A clip of the study could not be fetched, so the audit cannot run."""


def http_fetcher(base_url: str):
    """Return ``fetch(path) -> (status, headers, body)`` against a running server."""
    base = base_url.rstrip("/")

    def fetch(path):
        try:
            with urllib.request.urlopen(base + path, timeout=TIMEOUT) as response:
                return response.status, dict(response.headers.items()), response.read()
        except urllib.error.HTTPError as error:
            return error.code, dict(error.headers.items()), error.read()

    # Behind nginx with clips written ahead, the audit's items are written first too, so
    # it fetches them the way participants do (media.deliver_ahead).
    fetch.ahead = True
    return fetch


def view_fetcher():
    """Return ``fetch(path)`` that asks the clip view in this process (no server needed;
    what the view sends is what a participant receives, less the headers every response
    of the site has alike).

    Behind nginx (``STUDY_ACCEL_REDIRECT``) the view sends no bytes itself; here it streams
    them as it does without a proxy: the same delivery bytes nginx would send (the
    delivery's seeded file), and no delivery file is written. What nginx adds is audited
    through it with :func:`http_fetcher`."""
    from django.test import RequestFactory
    from django.test.utils import override_settings
    from django.urls import resolve

    from django.http import Http404

    factory = RequestFactory()

    def fetch(path):
        match = resolve(path)
        try:
            with override_settings(STUDY_ACCEL_REDIRECT=""):
                response = match.func(factory.get(path), **match.kwargs)
        except Http404:
            return 404, {}, b""
        body = b"".join(response.streaming_content) if response.streaming else response.content
        # Close the stored file, but not as the end of a request: that would also close
        # this process's database connection.
        for closer in getattr(response, "_resource_closers", []):
            closer()
        return response.status_code, dict(response.items()), body

    return fetch


def _show_everything(study, times: int) -> tuple[list[Participant], list[list[TrialItem]]]:
    """Return ``times`` audit participants, each shown every stimulus once (a practice
    trial), and the items of each stimulus (one per participant), by stimulus."""
    stimuli = list(Stimulus.objects.filter(study=study).exclude(
        role__in=[Stimulus.Role.EXAMPLE]).order_by("pk"))
    people, items = [], [[] for _ in stimuli]
    with transaction.atomic():
        for _ in range(times):
            person = Participant.objects.create(
                study=study, seed=0, external_key=f"{AUDIT_KEY}:{secrets.token_hex(4)}")
            people.append(person)
            trial = Trial.objects.create(participant=person, index=0, action="audit",
                                         kind=Trial.Kind.PRACTICE)
            made = TrialItem.objects.bulk_create(
                TrialItem(trial=trial, stimulus=s, position=i, required=False)
                for i, s in enumerate(stimuli))
            for k, (item, stimulus) in enumerate(zip(made, stimuli)):
                item.stimulus = stimulus
                items[k].append(item)
    return people, items


def _unavailable(item, what, url, status) -> str:
    return (f"the {what} of stimulus {item.stimulus} ({url}) answered HTTP {status}; "
            f"rebuild the study's stimuli (manage.py build_stimuli) where its files are "
            f"stored, or skip the audit with --no-audit")


def _delivery(item, fetch) -> dict:
    """Return ``{ext: (headers, bytes)}`` of every file of one item, fetched whole."""
    files = {}
    for ext, name, what in (("mp4", "video", "clip"), ("png", "poster", "poster"),
                            ("motion", "motion", "motion")):
        if ext != "mp4" and not getattr(item.stimulus, name):
            continue
        if getattr(fetch, "ahead", False):
            media.deliver_ahead(item.stimulus, item.token, ext)
        status, headers, body = fetch(item.clip_url(ext))
        if status != 200:
            raise AuditUnavailable(_unavailable(item, what, item.clip_url(ext), status))
        files[ext] = (headers, body)
    return files


def audit_study(study, fetch, level: str = "deep") -> dict:
    """Return the audit of ``study`` at ``level`` (``deep`` or ``basic``):
    ``{"<question>: <family>": entry}`` (see :func:`analysis.blindness.assess`), each
    entry with ``passed`` and ``says``.

    ``source`` asks real against generated among the judged clips (without real clips:
    the first source by name against the others); ``catch`` asks the catch clips among
    the catch and judged ones.
    """
    if level not in LEVELS:
        raise ValueError(f"audit level {level!r}; choose one of {', '.join(LEVELS)}")
    deep = level == "deep"
    people, items = _show_everything(study, DELIVERIES if deep else 1)
    try:
        clips = []
        for shown in items:
            stimulus = shown[0].stimulus
            clips.append(ClipRecord(role=stimulus.role, source=stimulus.source,
                                    action=stimulus.action,
                                    deliveries=[_delivery(item, fetch) for item in shown]))
    finally:
        for person in people:
            person.delete()
    return assess(clips, deep=deep)
