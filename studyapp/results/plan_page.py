"""The admin's plan page beside a study: power over participants x clips for its type.

The simulation runs outside the request (``tasks.run_job("call_command", ...)``, i.e. the
``plan`` command with the study's type); the page shows the latest ``plan.csv`` as a
table and ``power.png`` beside it.
"""

from datetime import datetime, timezone
from pathlib import Path

import pandas as pd
from django import forms
from django.conf import settings
from django.contrib import messages
from django.core.exceptions import PermissionDenied
from django.http import FileResponse, Http404
from django.shortcuts import get_object_or_404, redirect
from django.template.response import TemplateResponse

from analysis.simulate import STUDY_TYPES
from studyapp.survey.models import Study
from studyapp.survey.tasks import run_job


class PlanForm(forms.Form):
    """The assumptions of a plan; the study gives its type."""

    effect = forms.FloatField(initial=0.5, help_text="Strength of one source above another "
                              "(logit scale).")
    clip_sd = forms.FloatField(initial=0.5, min_value=0, help_text="SD of clip quality about "
                               "its source's strength (logit scale).")
    trials = forms.IntegerField(initial=10, min_value=1, help_text="Main trials per participant.")
    participants = forms.RegexField(initial="20,40,80", regex=r"^\d+(,\d+)*$",
                                    help_text="Numbers of participants to try, e.g. 20,40,80.")
    clips = forms.RegexField(initial="2,4,8", regex=r"^\d+(,\d+)*$",
                             help_text="Clips per source and condition to try.")
    studies = forms.IntegerField(initial=50, min_value=2, max_value=1000,
                                 help_text="Simulated studies per design.")
    clip_seconds = forms.FloatField(initial=3.0, min_value=0.1)
    reward_per_hour = forms.FloatField(initial=12.0, min_value=0)
    service_fee = forms.FloatField(initial=0.333, min_value=0,
                                   help_text="Prolific's service fee as a share of rewards "
                                             "(0.333: its academic rate when written, VAT not "
                                             "included).")


def plan_folder(study: Study) -> Path:
    """Return where the study's latest plan is written."""
    return Path(settings.VAR_DIR) / "plans" / study.slug


def start_plan(study: Study, options: dict) -> None:
    """Run ``plan`` for the study (its type, and minutes from its duration model) in the
    background."""
    run_job("call_command", name="plan",
            options={"study": study.slug, "study_type": study.study_type,
                     "out": str(plan_folder(study)), **options})


def plan_view(admin_site, request, pk):
    """Show the latest plan (staff who may view studies); a POST of the form starts a
    fresh one (staff who may change studies)."""
    study = get_object_or_404(Study, pk=pk)
    if not request.user.has_perm("survey.view_study"):
        raise PermissionDenied("viewing a plan needs the permission to view studies")
    if study.study_type not in STUDY_TYPES:
        raise Http404(f"no simulation of {study.study_type} studies to plan from")
    form = PlanForm(request.POST or None)
    if request.method == "POST":
        if not request.user.has_perm("survey.change_study"):
            raise PermissionDenied("starting a plan needs the permission to change studies")
        if form.is_valid():
            start_plan(study, form.cleaned_data)
            messages.info(request, "The plan is running; reload this page in a minute.")
            return redirect(request.path)
    table = plan_folder(study) / "plan.csv"
    written = (datetime.fromtimestamp(table.stat().st_mtime, tz=timezone.utc)
               if table.is_file() else None)
    rows = pd.read_csv(table).round(3).to_dict("records") if written else []
    context = {
        **admin_site.each_context(request),
        "title": f"Plan for {study.slug}",
        "study": study,
        "opts": Study._meta,
        "form": form,
        "written": written,
        "columns": list(rows[0]) if rows else [],
        "rows": rows,
    }
    return TemplateResponse(request, "admin/survey/study/plan.html", context)


def plan_figure_view(request, pk):
    """Return the latest plan's power plot."""
    study = get_object_or_404(Study, pk=pk)
    if not request.user.has_perm("survey.view_study"):
        raise PermissionDenied("viewing a plan needs the permission to view studies")
    figure = plan_folder(study) / "power.png"
    if not figure.is_file():
        raise Http404("no plan yet")
    return FileResponse(figure.open("rb"), content_type="image/png")
