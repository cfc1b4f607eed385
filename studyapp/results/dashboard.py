"""The admin's live dashboard of a study: how the study is going, refreshed as it goes.

A staff page beside the study (``/admin/survey/study/<pk>/dashboard/``) and its JSON
(``.../dashboard/data.json``, which the page fetches every ``STUDY_DASHBOARD_REFRESH_S``
seconds, 10 by default): participants by outcome over time, main-trial judgements per
source and condition against the plan, exclusions as they happen, the median time per
trial and per session, the predicted finish, the latest analysis with its intervals and
the blindness audit, and every clip by id with its preview.

Counts are aggregated in the database on every refresh. What needs the whole response
table (the exclusions, which :func:`analysis.study.apply_exclusions` finds with the very
rules ``analyze`` applies) or a planned session (the judgements per participant, the
session estimate of :mod:`~studyapp.participation.duration`) is computed once per state of the
answers and kept in Django's cache. The latest analysis is the one the Results page
shows (:func:`studyapp.results.analysis_page.latest_folder`, also one ``analyze --out`` wrote
elsewhere). Participants the bots of ``simulate_participants`` played are told by
their user agent and counted apart.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import random
import time
from datetime import datetime, timedelta, timezone as dt_timezone

from django.conf import settings
from django.core.cache import cache
from django.core.exceptions import PermissionDenied
from django.db.models import Count, Max, Min, Q
from django.db.models.functions import TruncDay, TruncHour, TruncMinute
from django.http import JsonResponse
from django.shortcuts import get_object_or_404
from django.template.loader import render_to_string
from django.template.response import TemplateResponse
from django.utils import timezone
from django.utils.html import format_html, format_html_join

from studyapp.results.audit import AUDIT_KEY
from studyapp.participation.bots import BOT_AGENTS
from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem
from studyapp.results.analysis_page import latest_folder

REFRESH_S = 10
CACHE_S = 3600
# Seconds the exclusions and the planned session of a study whose answers keep coming
# are reused before they are computed again (the response table is read for them).
RECOMPUTE_S = 30
TAKING_PART = "taking_part"  # the outcome key of participants still taking part
OUTCOME_COLOURS = {
    Participant.Outcome.COMPLETED: "#2e7d32",
    TAKING_PART: "#90caf9",
    Participant.Outcome.FAILED_ATTENTION: "#c62828",
    Participant.Outcome.TIMED_OUT: "#f9a825",
    Participant.Outcome.NO_CONSENT: "#9e9e9e",
    Participant.Outcome.SCREENED_OUT: "#6d4c41",
}
OUTCOME_LABELS = {TAKING_PART: "Taking part", **dict(Participant.Outcome.choices)}
RECENT_EXCLUSIONS = 20
BOT_COLOUR = "#6a1b9a"


def bot_q(prefix: str = "") -> Q:
    """Return the filter of participants a bot played (``prefix``: the path to them)."""
    q = Q()
    for agent in BOT_AGENTS:
        q |= Q(**{f"{prefix}user_agent__startswith": agent})
    return q


def people(study):
    """Return the study's participants, less the blindness audit's temporary ones."""
    return Participant.objects.filter(study=study).exclude(external_key__startswith=AUDIT_KEY)


def main_judgements(study):
    """Return the answered main-trial judged items of ``study`` (what the plan counts)."""
    return TrialItem.objects.judged().filter(
        trial__participant__study=study, trial__kind=Trial.Kind.MAIN,
        trial__answered_at__isnull=False)


# --- the data -----------------------------------------------------------------------


def dashboard_data(study: Study, now: datetime | None = None) -> dict:
    """Return everything the dashboard shows of ``study`` (JSON-able)."""
    now = now or timezone.now()
    state = _state(study)
    slow = _cached(study, state, lambda: _slow_parts(study))
    # The places held depend on the time limit, which may follow the session's minutes:
    # take them from the cache rather than planning a session on every refresh.
    participants = participant_counts(_with_minutes(study, slow["session"]["minutes"]), now)
    cells, clips = judgement_counts(study, slow["per_participant"])
    data = {
        "study": {"id": study.pk, "slug": study.slug, "title": study.title,
                  "type": study.kind.label, "status": study.status,
                  "places": study.max_participants},
        "generated_at": now.isoformat(),
        "participants": participants,
        "cells": cells,
        "judgements": sum(cell["judgements"] for cell in cells),
        "per_participant": slow["per_participant"],
        "judgements_target": (study.max_participants * slow["per_participant"]
                              if study.max_participants else None),
        "clips": clips,
        "exclusions": {**slow["exclusions"], "recent": recent_exclusions(study),
                       "counted_at": _text(datetime.fromtimestamp(slow["at"], dt_timezone.utc),
                                           seconds=True),
                       "recompute_s": recompute_seconds()},
        "timing": {**trial_times(study), "session": slow["session"]},
        "finish": predicted_finish(study, participants, slow["session"]["seconds"], now),
        "analysis": latest_analysis(study),
    }
    return data


def _with_minutes(study, minutes: int):
    """Return a copy of ``study`` whose ``minutes()`` is ``minutes`` (already found)."""
    found = copy.copy(study)
    found.minutes = lambda: minutes
    return found


def _state(study) -> dict:
    """Return what changes whenever an answer or a participant does (one aggregate each),
    and the settings the slow parts follow."""
    trials = Trial.objects.filter(participant__study=study, answered_at__isnull=False).aggregate(
        n=Count("pk"), last=Max("answered_at"))
    who = Participant.objects.filter(study=study).aggregate(
        n=Count("pk"), last=Max("completed_at"), outcomes=Count("outcome", filter=~Q(outcome="")))
    return {
        "answers": [trials["n"], str(trials["last"]), who["n"], str(who["last"]),
                    who["outcomes"]],
        "settings": [study.max_failed_catch, study.clips_per_trial,
                     study.trials_per_participant, study.catch_trials, study.practice,
                     study.repeat_trials, study.instructed_checks, study.stimuli.count(),
                     json.dumps(study.options or {}, sort_keys=True),
                     json.dumps(study.crowd or {}, sort_keys=True)],
    }


def recompute_seconds() -> float:
    """Return how long the slow parts of a busy study are kept while answers come in
    (the ``STUDY_DASHBOARD_RECOMPUTE_S`` setting, default ``RECOMPUTE_S``)."""
    return float(getattr(settings, "STUDY_DASHBOARD_RECOMPUTE_S", RECOMPUTE_S))


def _cached(study, state: dict, compute) -> dict:
    """Return ``compute()`` for the study as ``state`` says it is, from the cache when
    computed for the same state; while answers come in, the last result is kept for
    ``recompute_seconds()`` (its ``at`` says when it was counted) unless the settings
    changed."""
    digest = hashlib.sha1(json.dumps(state).encode()).hexdigest()
    key, latest_key = f"survey-dashboard:{study.pk}:{digest}", f"survey-dashboard:{study.pk}"
    found = _cache_get(key)
    if found is not None:
        return found
    latest = _cache_get(latest_key)
    if (latest is not None and latest.get("settings") == state["settings"]
            and time.time() - latest["at"] < recompute_seconds()):
        return latest
    found = {**compute(), "at": time.time(), "settings": state["settings"]}
    _cache_set(key, found)
    _cache_set(latest_key, found)
    return found


def _cache_get(key):
    try:
        return cache.get(key)
    except Exception:  # noqa: BLE001 - a cache that is down only costs the computation
        return None


def _cache_set(key, value) -> None:
    try:
        cache.set(key, value, CACHE_S)
    except Exception:  # noqa: BLE001
        pass


def _slow_parts(study) -> dict:
    """Return what needs a planned session or the response table."""
    found = study.duration()
    return {
        "per_participant": planned_judgements(study),
        "exclusions": exclusion_counts(study),
        "session": {"seconds": found.seconds, "minutes": found.minutes,
                    "measured": found.measured is not None, "says": found.describe()},
    }


def planned_judgements(study) -> int:
    """Return the main-trial judgements of judged clips one participant makes (a session
    planned as the next participant's would be; nothing is stored)."""
    plans = study.kind.plan_trials(study, random.Random(0))
    return sum(1 for plan in plans if plan.kind == Trial.Kind.MAIN
               for stimulus in plan.stimuli if stimulus.role == Stimulus.Role.JUDGED)


def participant_counts(study, now) -> dict:
    """Return participants by outcome (bots apart), the places held, and the arrivals by
    outcome over time."""
    rows = people(study).values("outcome").annotate(n=Count("pk"), bots=Count("pk", filter=bot_q()))
    by = {(row["outcome"] or TAKING_PART): row for row in rows}
    outcomes = [{"outcome": key, "label": label, "n": by[key]["n"] if key in by else 0,
                 "bots": by[key]["bots"] if key in by else 0, "colour": OUTCOME_COLOURS[key]}
                for key, label in OUTCOME_LABELS.items()]
    return {
        "outcomes": outcomes,
        "total": sum(o["n"] for o in outcomes),
        "bots": sum(o["bots"] for o in outcomes),
        "holding": Participant.objects.holding_a_place(study).exclude(
            external_key__startswith=AUDIT_KEY).count(),
        "timeline": timeline(study, now),
    }


def timeline(study, now) -> dict:
    """Return arrivals (``created_at``) by outcome, cumulative, in minutes, hours or days
    (whichever gives at most ~120 steps from the first arrival to now)."""
    first = people(study).aggregate(first=Min("created_at"))["first"]
    if first is None:
        return {"unit": "hour", "steps": []}
    span = now - first
    if span <= timedelta(hours=2):
        unit, trunc, step = "minute", TruncMinute, timedelta(minutes=1)
    elif span <= timedelta(days=5):
        unit, trunc, step = "hour", TruncHour, timedelta(hours=1)
    else:
        unit, trunc, step = "day", TruncDay, timedelta(days=1)
    rows = (people(study).annotate(at=trunc("created_at")).values("at", "outcome")
            .annotate(n=Count("pk"), bots=Count("pk", filter=bot_q())).order_by("at"))
    added, bots = {}, {}
    for row in rows:
        added.setdefault(row["at"], {})[row["outcome"] or TAKING_PART] = row["n"]
        bots[row["at"]] = bots.get(row["at"], 0) + row["bots"]
    steps, total, simulated = [], dict.fromkeys(OUTCOME_LABELS, 0), 0
    at = min(added)
    last = max(max(added), _truncate(now, unit))
    while at <= last and len(steps) < 400:
        for key, n in added.get(at, {}).items():
            total[key] += n
        simulated += bots.get(at, 0)
        steps.append({"at": at.isoformat(), "counts": dict(total), "bots": simulated})
        at += step
    return {"unit": unit, "steps": steps}


def _truncate(moment, unit):
    moment = moment.astimezone(dt_timezone.utc)
    if unit == "minute":
        return moment.replace(second=0, microsecond=0)
    if unit == "hour":
        return moment.replace(minute=0, second=0, microsecond=0)
    return moment.replace(hour=0, minute=0, second=0, microsecond=0)


def judgement_counts(study, per_participant: int) -> tuple[list, list]:
    """Return main-trial judgements per source and condition against the plan, and every
    clip with its own (both with the bots' share)."""
    counted = {row["stimulus"]: row for row in main_judgements(study).values("stimulus").annotate(
        n=Count("pk"), bots=Count("pk", filter=bot_q("trial__participant__")))}
    stimuli = list(Stimulus.objects.filter(study=study).order_by("action", "source", "pk").values(
        "pk", "action", "source", "role", "token", "poster", "duration"))
    cells = {}
    for s in stimuli:
        if s["role"] != Stimulus.Role.JUDGED:
            continue
        cell = cells.setdefault((s["action"], s["source"]), {
            "condition": s["action"], "source": s["source"], "clips": 0, "judgements": 0,
            "bots": 0})
        cell["clips"] += 1
        cell["judgements"] += counted.get(s["pk"], {}).get("n", 0)
        cell["bots"] += counted.get(s["pk"], {}).get("bots", 0)
    places = study.max_participants
    target = (places * per_participant / len(cells)) if places and cells else None
    for cell in cells.values():
        cell["target"] = round(target) if target is not None else None
        cell["share"] = (cell["judgements"] / target) if target else None
    from django.urls import reverse

    clips = []
    for s in stimuli:
        clips.append({
            "id": s["pk"], "condition": s["action"], "source": s["source"], "role": s["role"],
            "duration": s["duration"],
            "judgements": counted.get(s["pk"], {}).get("n", 0),
            "bots": counted.get(s["pk"], {}).get("bots", 0),
            "video": reverse("survey:preview_clip", args=[s["token"], "mp4"]),
            "poster": reverse("survey:preview_clip", args=[s["token"], "png"]) if s["poster"]
            else "",
        })
    return list(cells.values()), clips


def exclusion_counts(study) -> dict:
    """Return the exclusion table ``analyze --study`` would report now (its defaults and
    the study's ``max_failed_catch``), from the exported responses."""
    from analysis.study import AnalysisConfig, apply_exclusions, criteria_of
    from analysis.tables import AnalysisError
    from studyapp.results.export import responses_frame

    table = responses_frame(study)
    if table.empty:
        return {"rules": [], "notes": ["no answers yet"], "criterion": ""}
    criterion = criteria_of(table)[0]
    if criterion:
        table = table.loc[table["criterion"].astype(str) == criterion]
    config = AnalysisConfig(max_failed_catch=study.max_failed_catch, bootstrap=0,
                            type_options=dict(study.options or {}))
    try:
        _, excluded, notes = apply_exclusions(table, config)
    except AnalysisError as error:
        return {"rules": [], "notes": [str(error)], "criterion": criterion}
    rules = [{k: (int(v) if k in ("participants", "trials", "judgements") else str(v))
              for k, v in row.items()} for row in excluded.to_dict("records")]
    return {"rules": rules, "notes": list(notes), "criterion": criterion}


def recent_exclusions(study) -> list:
    """Return the latest participants who failed the attention checks, newest first."""
    rows = (people(study).filter(outcome=Participant.Outcome.FAILED_ATTENTION)
            .annotate(failed=Count("trials", filter=Q(trials__kind__in=Trial.CHECK_KINDS,
                                                      trials__catch_passed=False)),
                      bot=Count("pk", filter=bot_q()))
            .order_by("-completed_at").values("pk", "completed_at", "failed", "bot")
            [:RECENT_EXCLUSIONS])
    return [{"participant": row["pk"], "at": row["completed_at"].isoformat()
             if row["completed_at"] else None, "at_text": _text(row["completed_at"]),
             "failed_checks": row["failed"],
             "bot": bool(row["bot"])} for row in rows]


def _median(queryset, field: str):
    """Return the median of ``field`` over ``queryset``, found by the database (a count
    and one or two ordered rows)."""
    n = queryset.count()
    if not n:
        return None, 0
    ordered = queryset.order_by(field).values_list(field, flat=True)
    low, high = ordered[(n - 1) // 2], ordered[n // 2]
    return (low + high) / 2, n


def trial_times(study) -> dict:
    """Return the median seconds to answer a main trial (everyone, and people only when
    bots took part)."""
    answered = Trial.objects.filter(participant__study=study, kind=Trial.Kind.MAIN,
                                    answered_at__isnull=False, time_ms__isnull=False)
    median, n = _median(answered, "time_ms")
    out = {"median_trial_s": median / 1000 if median is not None else None, "n_trials": n}
    if answered.filter(bot_q("participant__")).exists():
        human, k = _median(answered.exclude(bot_q("participant__")), "time_ms")
        out.update(median_trial_people_s=human / 1000 if human is not None else None,
                   n_trials_people=k)
    return out


def predicted_finish(study, participants: dict, session_s: float, now) -> dict:
    """Return when the places fill at the arrival rate so far: arrivals (consents) per
    hour since the first, the places left (places less those finished or taking part),
    and the finish: the last arrival plus one session."""
    places = study.max_participants
    arrived = people(study).exclude(consented_at=None).aggregate(
        n=Count("pk"), first=Min("consented_at"))
    out = {"places": places, "arrived": arrived["n"], "holding": participants["holding"],
           "rate_per_hour": None, "left": None, "eta": None, "eta_text": ""}
    if arrived["n"] and arrived["first"] is not None:
        hours = max((now - arrived["first"]).total_seconds() / 3600, 1 / 60)
        out["rate_per_hour"] = arrived["n"] / hours
    if not places:
        out["says"] = ("No places set (the study's Max participants): no finish to predict.")
        return out
    left = max(0, places - participants["holding"])
    out["left"] = left
    if left == 0:
        taking = next(o["n"] for o in participants["outcomes"] if o["outcome"] == TAKING_PART)
        eta = now + timedelta(seconds=session_s) if taking else now
        out["eta"], out["eta_text"] = eta.isoformat(), _text(eta)
        out["says"] = (f"Every place is taken; the last of {taking} participants taking part "
                       f"should finish within one session." if taking
                       else "Every place is taken and finished.")
        return out
    if not out["rate_per_hour"]:
        out["says"] = f"{left} of {places} places left; nobody has arrived yet to give a rate."
        return out
    eta = now + timedelta(hours=left / out["rate_per_hour"], seconds=session_s)
    out["eta"], out["eta_text"] = eta.isoformat(), _text(eta)
    out["says"] = (f"{left} of {places} places left at {out['rate_per_hour']:.1f} arrivals per "
                   f"hour so far: the last arrives in about "
                   f"{_span(timedelta(hours=left / out['rate_per_hour']))} and finishes one "
                   f"session later.")
    return out


def _text(moment, seconds: bool = False) -> str:
    """Return a time as staff read it: ``2026-05-01 14:03`` (UTC)."""
    if not moment:
        return ""
    return moment.astimezone(dt_timezone.utc).strftime("%Y-%m-%d %H:%M" + (":%S" if seconds
                                                                           else ""))


def _span(delta: timedelta) -> str:
    minutes = delta.total_seconds() / 60
    if minutes < 90:
        return f"{minutes:.0f} minutes"
    if minutes < 48 * 60:
        return f"{minutes / 60:.1f} hours"
    return f"{minutes / 1440:.1f} days"


def latest_analysis(study) -> dict | None:
    """Return the latest analysis the Results page shows (``summary.json``, one per
    criterion), with its intervals and blindness audit, or None."""
    folder = latest_folder(study)
    found = []
    criteria = [""] + [c.key for c in study.kind.criteria(study)]
    for criterion in criteria:
        path = folder / criterion / "summary.json" if criterion else folder / "summary.json"
        if path.is_file():
            try:
                found.append((path, json.loads(path.read_text())))
            except (OSError, ValueError):
                continue
    if not found:
        return None
    written = max(path.stat().st_mtime for path, _ in found)
    parts, blindness = [], None
    for _, summary in found:
        parts.append({
            "criterion": summary.get("criterion", ""),
            "measure": summary.get("measure", ""),
            "confidence": summary.get("confidence"),
            "n_participants": summary.get("n_participants"),
            "n_judgements": summary.get("n_judgements"),
            "sources": [{"source": name, **(summary.get("sources") or {}).get(name, {})}
                        for name in summary.get("order", [])],
            "tests": _test_tables(summary.get("tests")),
            "notes": summary.get("notes", []),
        })
        blindness = blindness or summary.get("blindness")
    written = datetime.fromtimestamp(written, tz=dt_timezone.utc)
    return {
        "written": written.isoformat(),
        "written_text": _text(written),
        "criteria": parts,
        "blindness": [{"label": label, "passed": bool(part.get("passed")),
                       "says": part.get("says", "")} for label, part in (blindness or {}).items()],
    }


def _test_tables(tests) -> list:
    """Return the analysis' tests as small tables: ``[{"name", "columns", "rows"}]``."""
    out = []
    for name, value in (tests or {}).items():
        if isinstance(value, list) and value and all(isinstance(r, dict) for r in value):
            columns = list(value[0])
            out.append({"name": name, "columns": columns,
                        "rows": [[_short(r.get(c)) for c in columns] for r in value]})
        elif value is not None and not isinstance(value, (list, dict)):
            out.append({"name": name, "columns": ["value"], "rows": [[_short(value)]]})
    return out


def _short(value):
    return f"{value:.3g}" if isinstance(value, float) else value


# --- the chart ----------------------------------------------------------------------


def timeline_svg(line: dict, width: int = 720, height: int = 180) -> str:
    """Return an inline SVG of cumulative arrivals by outcome (stacked bars), drawn here."""
    steps = line["steps"]
    if not steps:
        return format_html('<p class="help">{}</p>', "Nobody has arrived yet.")
    top = max(sum(step["counts"].values()) for step in steps) or 1
    left, bottom, plot_h = 36, 20, height - 30
    bar = (width - left - 4) / len(steps)
    rects = []
    for k, step in enumerate(steps):
        y = 10 + plot_h
        for key in OUTCOME_LABELS:
            n = step["counts"].get(key, 0)
            if not n:
                continue
            h = plot_h * n / top
            y -= h
            rects.append((f"{left + k * bar + 0.5:.1f}", f"{y:.1f}", f"{max(bar - 1, 0.5):.1f}",
                          f"{h:.1f}", OUTCOME_COLOURS[key],
                          f"{step['at'][:16].replace('T', ' ')}: {n} {OUTCOME_LABELS[key]}"))
    body = format_html_join("", '<rect x="{}" y="{}" width="{}" height="{}" fill="{}">'
                            '<title>{}</title></rect>', rects)
    if steps[-1].get("bots"):  # the simulated participants among them: a dashed line
        points = " ".join(
            f"{left + (k + 0.5) * bar:.1f},{10 + plot_h - plot_h * step['bots'] / top:.1f}"
            for k, step in enumerate(steps))
        if len(steps) == 1:
            x, y = points.split(",")
            points = f"{left},{y} {left + bar:.1f},{y}"
        body = format_html('{}<polyline class="bots" points="{}" fill="none" stroke="{}" '
                           'stroke-width="3" stroke-dasharray="5 3"><title>{} simulated '
                           '(bots)</title></polyline>', body, points, BOT_COLOUR,
                           steps[-1]["bots"])
    first, last = steps[0]["at"][:16].replace("T", " "), steps[-1]["at"][:16].replace("T", " ")
    return format_html(
        '<svg class="dashboard-timeline" role="img" viewBox="0 0 {w} {h}" width="{w}" '
        'height="{h}" aria-label="Participants by outcome over time (cumulative, by arrival '
        '{unit})"><line x1="{l}" y1="10" x2="{l}" y2="{base}" stroke="#888"/>'
        '<line x1="{l}" y1="{base}" x2="{w}" y2="{base}" stroke="#888"/>'
        '<text x="{tx}" y="16" font-size="10" text-anchor="end">{top}</text>'
        '<text x="{tx}" y="{base}" font-size="10" text-anchor="end">0</text>{body}'
        '<text x="{l}" y="{lab}" font-size="10">{first}</text>'
        '<text x="{w}" y="{lab}" font-size="10" text-anchor="end">{last} UTC</text></svg>',
        w=width, h=height, l=left, base=10 + plot_h, tx=left - 4, top=top, body=body,
        lab=height - bottom + 16, first=first, last=last, unit=line["unit"])


# --- the views ----------------------------------------------------------------------


def _allowed(request, pk) -> Study:
    study = get_object_or_404(Study, pk=pk)
    if not request.user.has_perm("survey.view_study"):
        raise PermissionDenied("the dashboard needs the permission to view studies")
    return study


def refresh_seconds() -> float:
    """Return the seconds between refreshes: the Django setting, else the environment
    variable ``STUDY_DASHBOARD_REFRESH_S``, else ``REFRESH_S``."""
    found = getattr(settings, "STUDY_DASHBOARD_REFRESH_S", None)
    if found is None:
        found = os.environ.get("STUDY_DASHBOARD_REFRESH_S", "") or REFRESH_S
    try:
        return max(1.0, float(found))
    except ValueError:
        return float(REFRESH_S)


def sections_html(study, data) -> str:
    """Return the dashboard's sections (what a refresh replaces)."""
    context = {"study": study, "data": data,
               "timeline": timeline_svg(data["participants"]["timeline"])}
    return render_to_string("admin/survey/study/dashboard_sections.html", context)


def dashboard_view(admin_site, request, pk):
    """Show the dashboard (staff who may view studies)."""
    study = _allowed(request, pk)
    data = dashboard_data(study)
    context = {
        **admin_site.each_context(request),
        "title": f"Dashboard of {study.slug}",
        "study": study,
        "opts": Study._meta,
        "sections": sections_html(study, data),
        "refresh_ms": int(refresh_seconds() * 1000),
    }
    return TemplateResponse(request, "admin/survey/study/dashboard.html", context)


def dashboard_data_view(request, pk):
    """Return the dashboard's data and its sections' HTML (what the page refreshes from)."""
    study = _allowed(request, pk)
    data = dashboard_data(study)
    response = JsonResponse({"data": data, "html": sections_html(study, data)})
    response["Cache-Control"] = "no-store"
    return response
