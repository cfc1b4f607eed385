"""Run the blindness audit (:mod:`analysis.blindness`) on a built study, through HTTP.

The audit shows every clip of the study to a temporary audit participant (a practice
trial, so no balance count changes; never consented, so it holds no place) and fetches
each clip and poster under that participant's item tokens, exactly as a participant's
browser would, from the server at ``url`` (or in-process from the clip view, as
``analyze`` does). The audit participant is deleted afterwards.
"""

from __future__ import annotations

import secrets
import urllib.error
import urllib.request

from django.db import transaction

from analysis.blindness import audit, clip_features
from studyapp.survey.models import Participant, Stimulus, Trial, TrialItem

AUDIT_KEY = "audit:blindness"
TIMEOUT = 30


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

    return fetch


def view_fetcher():
    """Return ``fetch(path)`` that asks the clip view in this process (no server needed;
    what the view sends is what a participant receives, less the headers every response
    of the site has alike)."""
    from django.test import RequestFactory
    from django.urls import resolve

    from django.http import Http404

    factory = RequestFactory()

    def fetch(path):
        match = resolve(path)
        try:
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


def _show_everything(study) -> tuple[Participant, list[TrialItem]]:
    stimuli = list(Stimulus.objects.filter(study=study).exclude(
        role__in=[Stimulus.Role.EXAMPLE]).order_by("pk"))
    with transaction.atomic():
        person = Participant.objects.create(
            study=study, seed=0, external_key=f"{AUDIT_KEY}:{secrets.token_hex(4)}")
        trial = Trial.objects.create(participant=person, index=0, action="audit",
                                     kind=Trial.Kind.PRACTICE)
        items = TrialItem.objects.bulk_create(
            TrialItem(trial=trial, stimulus=s, position=i, required=False)
            for i, s in enumerate(stimuli))
    for item, stimulus in zip(items, stimuli):
        item.stimulus = stimulus
    return person, items


def _unavailable(item, what, url, status) -> str:
    return (f"the {what} of stimulus {item.stimulus} ({url}) answered HTTP {status}; "
            f"rebuild the study's stimuli (manage.py build_stimuli) where its files are "
            f"stored, or skip the audit with --no-audit")


def audit_study(study, fetch) -> dict:
    """Return ``{"source": {...}, "catch": {...}}`` for ``study`` (see the module docstring).

    ``source`` predicts real vs generated among the judged clips (without real clips: the
    first source by name vs the others); ``catch`` predicts the
    broken catch clips among the catch and judged ones. Each entry has ``accuracy``,
    ``chance``, ``n``, ``margin`` and ``passed``.
    """
    person, items = _show_everything(study)
    try:
        rows, kinds = [], []
        for item in items:
            status, headers, body = fetch(item.clip_url("mp4"))
            if status != 200:
                raise AuditUnavailable(_unavailable(item, "clip", item.clip_url("mp4"), status))
            extra = {}
            for ext, name in (("png", "poster"), ("motion", "motion")):
                if getattr(item.stimulus, name):
                    code, extra[f"{name}_headers"], extra[name] = fetch(item.clip_url(ext))
                    if code != 200:
                        raise AuditUnavailable(_unavailable(item, name, item.clip_url(ext), code))
            rows.append(clip_features(body, headers, **extra))
            kinds.append((item.stimulus.role, item.stimulus.source))
    finally:
        person.delete()
    judged = [i for i, (role, _) in enumerate(kinds) if role == Stimulus.Role.JUDGED]
    shown = [i for i, (role, _) in enumerate(kinds) if role in (Stimulus.Role.JUDGED,
                                                                Stimulus.Role.CATCH)]
    # Real against generated; in a study without real clips (e.g. two text-to-motion
    # models), the first source by name against the others.
    sources = sorted({kinds[i][1] for i in judged})
    told = "real" if "real" in sources or not sources else sources[0]
    return {
        "source": audit([rows[i] for i in judged], [kinds[i][1] == told for i in judged]),
        "catch": audit([rows[i] for i in shown],
                       [kinds[i][0] == Stimulus.Role.CATCH for i in shown]),
    }


def passed(result: dict) -> bool:
    return all(part["passed"] for part in result.values())
