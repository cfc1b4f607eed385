"""The researcher's preview: the study's pages as a participant sees them, storing nothing.

A staff member walks the same ``PAGE_SEQUENCE`` as participants (:mod:`.flow`), in any
study status, over :class:`PreviewStore`: a store whose participant lives in the
reviewer's own session cookie as plain data (the planned session as stimulus ids, the
page reached). Trials are unsaved model objects; answers are checked by the same forms,
then dropped. No participant, trial or answer is written, and the balance counts of real
participants are only read. Clips are served under the stimuli's staff-only URLs, so the
server's watch check does not apply.
"""

from __future__ import annotations

import random

from django.shortcuts import redirect
from django.urls import reverse

from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem


def state_key(study) -> str:
    return f"survey-preview:{study.pk}"


class PreviewParticipant:
    """A participant as plain session data; has what the pages ask of a participant."""

    def __init__(self, study, state: dict):
        self.study, self.state = study, state
        self.pk = None
        self.external_key = ""
        self.trials_planned = state.get("trials", [])
        self.n_trials = len(self.trials_planned)
        self.n_practice = sum(t["kind"] == Trial.Kind.PRACTICE for t in self.trials_planned)
        self.consented_at = state.get("consented")
        self.outcome = state.get("outcome", "")
        self.completed_at = "preview" if self.outcome else None
        self.completion_code = "PREVIEW" if self.outcome else ""
        self.demographics = state.get("demographics")
        self.external_ids = {}

    def is_finished(self):
        return self.completed_at is not None

    def has_trials(self):
        return bool(self.trials_planned) or self.state.get("started", False)

    def timed_out(self):
        return False


class PreviewStore:
    """The flow's store for previews (see the module docstring)."""

    preview = True

    def __init__(self, request):
        self.request = request

    def _state(self, study) -> dict | None:
        return self.request.session.get(state_key(study))

    def _save(self, study, state) -> None:
        self.request.session[state_key(study)] = state

    def url(self, study, name: str) -> str:
        return reverse("survey:preview_page", args=[study.slug, name])

    def participant(self, request, study):
        state = self._state(study)
        return PreviewParticipant(study, state) if state is not None else None

    def enroll(self, request, study, outcome: str = ""):
        state = {"consented": None if outcome else "preview", "outcome": outcome,
                 "trials": [], "index": 0}
        self._save(study, state)
        return PreviewParticipant(study, state)

    def start(self, request, participant) -> None:
        state = participant.state
        state["trials"] = plan(participant.study)
        state["started"] = True
        state["index"] = 0
        self._save(participant.study, state)
        participant.trials_planned = state["trials"]
        participant.n_trials = len(state["trials"])

    def current_trial(self, request, participant):
        state = participant.state
        index = state["index"]
        trial, items = unsaved_trial(participant, state["trials"][index], index)
        practice = participant.n_practice
        number = None if trial.kind == Trial.Kind.PRACTICE else index + 1 - practice
        return trial, items, number, participant.n_trials - practice

    def posted_trial(self, request, participant):
        index = participant.state["index"]
        if request.POST.get("trial") != str(index):
            return None, [], "This is not the question you are on."
        trial, items = unsaved_trial(participant, participant.state["trials"][index], index)
        return trial, items, None

    def advance(self, participant, trial) -> bool:
        return True  # ``record_answer`` moved the index on

    def clip_url(self, item, ext="mp4") -> str:
        return item.stimulus.preview_url(ext)

    def watch_problems(self, trial, items, labels) -> list[str]:
        return []

    def record_answer(self, request, trial, answer, items) -> bool:
        participant = trial.previewer
        state = participant.state
        state["index"] += 1
        if state["index"] >= len(state["trials"]):
            state["outcome"] = Participant.Outcome.COMPLETED
        self._save(participant.study, state)
        return True

    def record_demographics(self, request, participant, answers) -> None:
        participant.state["demographics"] = answers
        self._save(participant.study, participant.state)

    def timed_out(self, participant) -> bool:
        return False


def start(request, study):
    """Begin a fresh preview of ``study`` at its consent page."""
    request.session.pop(state_key(study), None)
    return redirect(reverse("survey:preview_page", args=[study.slug, "consent"]))


def plan(study: Study) -> list[dict]:
    """Return a session planned as for a new participant, as plain data."""
    plans = study.kind.plan_trials(study, random.Random())
    return [
        {
            "action": p.action,
            "kind": p.kind,
            "stimuli": [stimulus.pk for stimulus in p.stimuli],
            "shown": [[stimulus.pk, role, required] for stimulus, role, required in p.shown],
            "instruction": p.instruction,
        }
        for p in plans
    ]


def unsaved_trial(participant, planned: dict, index: int):
    """Return an unsaved trial and its items, never to be written."""
    ids = planned["stimuli"] + [pk for pk, _, _ in planned["shown"]]
    stimuli = Stimulus.objects.in_bulk(ids)
    first = stimuli[planned["stimuli"][0]] if planned["stimuli"] else None
    trial = Trial(index=index, action=planned["action"], kind=planned["kind"],
                  prompt=first.prompt if first else "",
                  instruction=planned.get("instruction") or {})
    trial.previewer = participant  # not a model instance: never assigned as the FK
    items = [
        TrialItem(trial=trial, stimulus=stimuli[pk], position=position)
        for position, pk in enumerate(planned["stimuli"])
    ]
    for pk, role, required in planned["shown"]:
        items.append(TrialItem(trial=trial, stimulus=stimuli[pk], role=role,
                               position=len(items), required=required))
    for position, item in enumerate(items):
        # Unsaved, but answers are keyed by item id and fields by token: both must be the
        # same when the page is shown and when it is answered.
        item.pk = -(position + 1)
        item.token = f"preview-{index}-{position}"
    return trial, items
