"""The researcher's preview: a study's pages as a participant sees them, storing nothing.

A staff member walks the same pages (consent, instructions, practice and trials,
closing questions, completion) in any study status. The planned session lives in
their own session cookie as stimulus ids; trials are unsaved model objects; answers
are checked by the same forms, then dropped. No participant, trial or answer is
written, and the balance counts of real participants are only read.
"""

import random
from types import SimpleNamespace

from django.shortcuts import redirect, render
from django.urls import reverse

from studyapp.survey.flow import render_trial
from studyapp.survey.forms import ConsentForm, DemographicsForm
from studyapp.survey.models import Participant, Stimulus, Trial, TrialItem

PAGES = ("consent", "instructions", "trial", "about-you", "done")
TEMPLATES = {
    "consent": "survey/consent.html",
    "instructions": "survey/instructions.html",
    "about-you": "survey/demographics.html",
    "done": "survey/done.html",
}


def state_key(study) -> str:
    return f"survey-preview:{study.pk}"


def url(study, name: str) -> str:
    return reverse("survey:preview_page", args=[study.slug, name])


def start(request, study):
    """Begin a fresh preview of ``study`` at its consent page."""
    request.session[state_key(study)] = {"page": "consent", "trials": [], "index": 0}
    return redirect(url(study, "consent"))


def plan(study) -> list[dict]:
    """Return a session planned as for a new participant, as plain data."""
    plans = study.kind.plan_trials(study, random.Random())
    return [
        {
            "action": p.action,
            "kind": p.kind,
            "stimuli": [stimulus.pk for stimulus in p.stimuli],
            "reference": p.reference.pk if p.reference else None,
        }
        for p in plans
    ]


def unsaved_trial(study, planned: dict, index: int):
    """Return an unsaved trial and its items, never to be written."""
    stimuli = Stimulus.objects.in_bulk(planned["stimuli"] + [planned["reference"]])
    trial = Trial(
        participant=Participant(study=study),
        index=index,
        action=planned["action"],
        kind=planned["kind"],
        reference=stimuli.get(planned["reference"]),
    )
    items = [
        TrialItem(trial=trial, stimulus=stimuli[pk], position=position)
        for position, pk in enumerate(planned["stimuli"])
    ]
    return trial, items


def show(request, study, name: str):
    """Render or submit preview page ``name``; keep the reviewer on their current page."""
    state = request.session.get(state_key(study))
    if state is None:
        return start(request, study)
    if name != state["page"]:
        return redirect(url(study, state["page"]))
    if request.method == "POST":
        return advance(request, study, state)
    context = {"study": study, "preview": True, "page": name}
    if name == "trial":
        return trial_page(request, study, state)
    if name == "consent":
        context["form"] = ConsentForm()
    elif name == "about-you":
        context["form"] = DemographicsForm()
    elif name == "done":
        context["participant"] = SimpleNamespace(completion_code="PREVIEW")
    return render(request, TEMPLATES[name], context)


def trial_page(request, study, state, errors=None):
    trials = state["trials"]
    index = state["index"]
    trial, items = unsaved_trial(study, trials[index], index)
    practice = sum(t["kind"] == Trial.Kind.PRACTICE for t in trials)
    number = None if trial.kind == Trial.Kind.PRACTICE else index + 1 - practice
    return render_trial(
        request,
        study,
        trial,
        items,
        number,
        len(trials) - practice,
        practice_over=practice and number == 1,
        trial_key=index,
        preview=True,
        preview_errors=errors,
    )


def advance(request, study, state):
    """Check the posted page like the real one would, then move on, storing nothing."""
    page = state["page"]
    if page == "consent":
        form = ConsentForm(request.POST)
        if not form.is_valid():
            return render(request, TEMPLATES[page], {"study": study, "form": form, "preview": True})
        state.update(page="instructions", trials=plan(study), index=0)
    elif page == "instructions":
        state["page"] = "trial" if state["trials"] else next_after_trials(study)
    elif page == "trial":
        if request.POST.get("trial") != str(state["index"]):
            return redirect(url(study, page))
        trial, items = unsaved_trial(study, state["trials"][state["index"]], state["index"])
        form = study.kind.answer_form(trial, items, request.POST)
        if not form.is_valid():
            return trial_page(request, study, state, errors=form.messages())
        state["index"] += 1
        if state["index"] == len(state["trials"]):
            state["page"] = next_after_trials(study)
    elif page == "about-you":
        state["page"] = "done"
    request.session[state_key(study)] = state
    return redirect(url(study, state["page"]))


def next_after_trials(study) -> str:
    return "about-you" if study.ask_demographics else "done"
