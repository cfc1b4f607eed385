"""An arena's public leaderboard (``/arena/<slug>/`` and ``/arena/<slug>.json``), read-only
and without login.

Per source: its score (the type's worth, e.g. the Bradley-Terry log-worth) with the
interval over participants and clips of :mod:`analysis.crossed` (the analysis ``analyze``
runs, its exclusions included), its difference from the fixed baseline with its interval
(a scale that does not move as sources join and leave, as the centred worths do), its votes (judgements after exclusions), "preliminary"
below the arena's ``min_votes``, the anchors (real motion capture and the fixed baseline)
and retired sources, marked. It names sources, as a leaderboard does; it is a page of its
own, and nothing on the participants' pages changes.

The computation reads the whole response table and bootstraps, so a request never runs
it: :func:`compute` stores the board in ``Study.arena_state`` (the ``arena board``
command, run in the background), and a request for a board older than the arena's
``refresh_seconds`` while answers came in since, or older than the last source added or
retired, asks for that job (once per period) and serves the stored board meanwhile.
"""

from __future__ import annotations

import math
from datetime import datetime

from django.db import transaction
from django.http import Http404, JsonResponse
from django.shortcuts import render
from django.utils import timezone
from django.views.decorators.http import require_GET

from analysis.study import AnalysisConfig, analyse
from analysis.tables import AnalysisError
from studyapp.participation.arena import is_arena, retired, settings
from studyapp.results.export import responses_frame
from studyapp.survey.models import Participant, Stimulus, Study, Trial
from studyapp.survey.tasks import run_job

BOOTSTRAP = 1000


def completed_answers(study) -> int:
    """The main trials answered by participants who completed the study: the only answers a
    board counts. A session still running never moves the board, so nobody can answer a
    trial, reload the board and read which two sources they were just shown."""
    return Trial.objects.filter(participant__study=study, kind=Trial.Kind.MAIN,
                                answered_at__isnull=False,
                                participant__outcome=Participant.Outcome.COMPLETED).count()


def compute(study, bootstrap: int = BOOTSTRAP) -> dict:
    """Compute the leaderboard of ``study`` now, from completed participants only, and
    store it."""
    chosen = settings(study)
    answers = completed_answers(study)
    names = sorted(set(Stimulus.objects.judged().filter(study=study)
                       .values_list("source", flat=True)))
    rows, note, measure, differences = {}, "", "", None
    table = responses_frame(study)
    if len(table):
        config = AnalysisConfig(max_failed_catch=study.max_failed_catch, bootstrap=bootstrap,
                                completed_only=True,
                                type_options={k: study.option(k) for k in study.kind.options})
        try:
            result = analyse(table, config)
        except AnalysisError as exc:
            note = str(exc)
        else:
            sources = result.analysis.sources
            for name, row in sources.iterrows():
                rows[str(name)] = {key: _number(row.get(key)) for key in
                                   ("score", "ci_low", "ci_high", "n_judgements",
                                    "n_participants")}
            note = " ".join(result.notes)
            measure = result.analysis.measure
            differences = result.analysis.tests.get("differences")
    else:
        note = "no answers yet"
    gone = set(retired(study))
    anchors = {chosen["real"]: "real motion capture", chosen["baseline"]: "baseline"}
    entries = []
    for name in sorted(set(names) | set(rows)):
        found = rows.get(name, {})
        votes = int(found.get("n_judgements") or 0)
        entries.append({
            "source": name, "score": found.get("score"), "ci_low": found.get("ci_low"),
            "ci_high": found.get("ci_high"), "votes": votes,
            "participants": int(found.get("n_participants") or 0),
            "preliminary": votes < chosen["min_votes"] or found.get("score") is None,
            "anchor": anchors.get(name), "retired": name in gone,
            "vs_baseline": _versus(differences, name, chosen["baseline"]),
        })
    entries.sort(key=lambda e: (e["score"] is None, -(e["score"] or 0.0), e["source"]))
    for rank, entry in enumerate(entries, 1):
        entry["rank"] = rank if entry["score"] is not None else None
    board = {"study": study.slug, "title": study.title, "computed_at": timezone.now().isoformat(),
             "answers": answers, "min_votes": chosen["min_votes"],
             "measure": measure, "interval": "95 % over participants and clips",
             "note": note, "sources": entries}
    with transaction.atomic():
        locked = Study.objects.lock(study.pk)
        state = {**(locked.arena_state or {}), "board": board}
        state.pop("board_requested", None)
        Study.objects.filter(pk=study.pk).update(arena_state=state)
    study.arena_state = state
    return board


def _versus(differences, name: str, anchor) -> dict | None:
    """Return ``name``'s difference from the ``anchor`` source with its crossed interval
    (from the analysis' table of differences), or None."""
    if differences is None or anchor is None or name == anchor:
        return None
    for a, b, sign in ((name, anchor, 1.0), (anchor, name, -1.0)):
        found = differences.loc[(differences["a"] == a) & (differences["b"] == b)]
        if len(found):
            row = found.iloc[0]
            low, high = _number(sign * row["ci_low"]), _number(sign * row["ci_high"])
            return {"difference": _number(sign * row["difference"]),
                    "ci_low": low if sign > 0 else high, "ci_high": high if sign > 0 else low}
    return None


def _number(value):
    if value is None:
        return None
    value = float(value)
    return None if math.isnan(value) else round(value, 4)


def stored(study) -> dict | None:
    """Return the stored board, asking for a fresh one in the background when it is stale:
    older than ``refresh_seconds`` with answers since (or none stored), and not asked
    for within that period."""
    state = study.arena_state or {}
    board = state.get("board")
    now = timezone.now()
    period = settings(study)["refresh_seconds"]
    if board is not None and board["computed_at"] >= state.get("changed_at", ""):
        age = (now - datetime.fromisoformat(board["computed_at"])).total_seconds()
        if age < period or completed_answers(study) == board["answers"]:
            return board
    asked = state.get("board_requested")
    if asked and (now - datetime.fromisoformat(asked)).total_seconds() < max(period, 1):
        return board
    with transaction.atomic():
        locked = Study.objects.lock(study.pk)
        if (locked.arena_state or {}).get("board_requested") != asked:
            return board  # another request asked meanwhile
        Study.objects.filter(pk=study.pk).update(
            arena_state={**(locked.arena_state or {}), "board_requested": now.isoformat()})
        transaction.on_commit(lambda: run_job("call_command", name="arena",
                                              args=["board", "--study", study.slug]))
    return board


def _arena(slug):
    study = Study.objects.filter(slug=slug).first()
    if study is None or not is_arena(study):
        raise Http404("no such arena")
    return study


@require_GET
def page(request, slug):
    study = _arena(slug)
    board = stored(study)
    response = render(request, "results/arena.html", {"study": study, "board": board})
    response["Cache-Control"] = "public, max-age=30"
    return response


@require_GET
def data(request, slug):
    study = _arena(slug)
    board = stored(study)
    response = JsonResponse(board or {"study": study.slug, "sources": [],
                                      "note": "the leaderboard is being computed"})
    response["Cache-Control"] = "public, max-age=30"
    return response
