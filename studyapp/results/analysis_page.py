"""The admin's results page of a study: the analysis report, refreshed as a background job.

The analysis runs outside the request (``tasks.run_job("call_command", ...)``, i.e. the
``analyze`` command); the page shows the latest ``report.html`` it wrote.
"""

import json
from datetime import datetime, timezone
from pathlib import Path

from django.conf import settings
from django.contrib import messages
from django.core.exceptions import PermissionDenied
from django.http import FileResponse, Http404
from django.views.decorators.clickjacking import xframe_options_sameorigin
from django.shortcuts import get_object_or_404, redirect
from django.template.response import TemplateResponse

from studyapp.survey.models import Study


def report_folder(study: Study) -> Path:
    """Return where the study's latest analysis is written."""
    return Path(settings.VAR_DIR) / "reports" / study.slug


POINTER = "latest.json"  # in report_folder: where the latest analysis went (``analyze --out``)


def note_report(study: Study, out: Path) -> None:
    """Note that ``analyze --out`` wrote the study's latest analysis to ``out``, so the
    Results page shows it wherever it went."""
    folder = report_folder(study)
    out = Path(out).resolve()
    if out == folder.resolve():
        (folder / POINTER).unlink(missing_ok=True)
        return
    folder.mkdir(parents=True, exist_ok=True)
    (folder / POINTER).write_text(json.dumps({"study": _identity(study), "folder": str(out)}))


def _identity(study: Study) -> str:
    """Return what tells this study from another of its slug (made before or elsewhere)."""
    return f"{study.pk}:{study.created_at.isoformat() if study.created_at else ''}"


def latest_folder(study: Study) -> Path:
    """Return the folder of the study's latest analysis: the Results page's own, or the
    ``--out`` of the last ``analyze`` run from the command line when that is newer."""
    own = report_folder(study)
    pointer = own / POINTER
    if not pointer.is_file():
        return own
    try:
        noted = json.loads(pointer.read_text())
        other = Path(noted["folder"])
    except (OSError, ValueError, KeyError, TypeError):
        return own
    if noted.get("study") != _identity(study) or not (other / "report.html").is_file():
        return own
    if (own / "report.html").is_file() and (
            (own / "report.html").stat().st_mtime > (other / "report.html").stat().st_mtime):
        return own
    return other


def start_analysis(study: Study) -> None:
    """Run ``analyze`` for the study in the background."""
    from studyapp.survey.tasks import run_job

    run_job("call_command", name="analyze",
            options={"study": study.slug, "out": str(report_folder(study))})


def results_view(admin_site, request, pk):
    """Show the latest report (staff who may view studies); a POST starts a fresh
    analysis (staff who may change studies)."""
    study = get_object_or_404(Study, pk=pk)
    if not request.user.has_perm("survey.view_study"):
        raise PermissionDenied("viewing results needs the permission to view studies")
    if request.method == "POST":
        if not request.user.has_perm("survey.change_study"):
            raise PermissionDenied("starting an analysis needs the permission to change studies")
        start_analysis(study)
        messages.info(request, "The analysis is running; reload this page in a few seconds.")
        return redirect(request.path)
    report = latest_folder(study) / "report.html"
    written = (
        datetime.fromtimestamp(report.stat().st_mtime, tz=timezone.utc) if report.is_file() else None
    )
    context = {
        **admin_site.each_context(request),
        "title": f"Results of {study.slug}",
        "study": study,
        "opts": Study._meta,
        "written": written,
    }
    return TemplateResponse(request, "admin/survey/study/results.html", context)


@xframe_options_sameorigin  # shown in the Results page's frame, on this site only
def report_view(request, pk, criterion=None):
    """Return the study's latest ``report.html`` (self-contained, figures embedded).

    A study asking several questions has one report per ``criterion`` (its key) beside
    an index linking them.
    """
    if not request.user.has_perm("survey.view_study"):
        raise PermissionDenied("viewing results needs the permission to view studies")
    study = get_object_or_404(Study, pk=pk)
    folder = latest_folder(study)
    if criterion is not None:
        if criterion not in [c.key for c in study.kind.criteria(study)]:
            raise Http404("the study asks no such question")
        folder = folder / criterion
    report = folder / "report.html"
    if not report.is_file():
        raise Http404("no analysis yet")
    return FileResponse(open(report, "rb"), content_type="text/html; charset=utf-8")
