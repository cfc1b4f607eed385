"""A participant's path through a study, declared as data (as in oTree).

``PAGE_SEQUENCE`` lists the pages; the participant is always sent to the first page
they have not finished, so a reload, a back button or a stale tab lands where they
are. The participant is found through their token in a signed cookie of the study
(no session row is read or written on a participant's pages).
"""

import logging

from django.conf import settings
from django.core import signing
from django.shortcuts import redirect, render
from django.urls import reverse

from studyapp.survey.forms import ConsentForm, DemographicsForm
from studyapp.survey.models import (
    EXTERNAL_PARAMS,
    Participant,
    Study,
    Trial,
    TrialItem,
    Unavailable,
    external_key,
)

MAX_ID_LENGTH = 100
# Browsers drop cookies over 4 KB; crowd ids are short, so longer ones are cut further.
MAX_COOKIE_BYTES = 3000
SHORT_ID_LENGTH = 30

log = logging.getLogger(__name__)


COOKIE_SALT = "studyapp.survey.participant"
COOKIE_AGE_S = 60 * 60 * 24 * 30


def cookie_name(study) -> str:
    return f"study{study.pk}"


def browser_state(request, study) -> dict:
    """Return what this browser's cookie says about ``study``: ``{"p": token}`` for a
    participant, ``{"x": {...}}`` for the platform ids of someone not yet consenting,
    or ``{}`` (no cookie, or one that was not signed here)."""
    states = request.__dict__.setdefault("survey_states", {})
    if study.pk not in states:
        raw = request.COOKIES.get(cookie_name(study), "")
        try:
            state = signing.loads(raw, salt=COOKIE_SALT, max_age=COOKIE_AGE_S) if raw else {}
        except signing.BadSignature:
            state = {}
        states[study.pk] = state if isinstance(state, dict) else {}
    return states[study.pk]


def set_browser_state(request, study, state: dict) -> None:
    """Change the cookie of ``study``; ``keep_browser_state`` writes it on the response."""
    browser_state(request, study)
    request.survey_states[study.pk] = state
    request.__dict__.setdefault("survey_changed", set()).add(study)


def keep_browser_state(request, response):
    """Write the cookies changed while answering ``request`` onto ``response``."""
    for study in getattr(request, "survey_changed", ()):
        state = request.survey_states[study.pk]
        value = signing.dumps(state, salt=COOKIE_SALT, compress=True)
        if len(value) > MAX_COOKIE_BYTES and "x" in state:
            short = {name: id_[:SHORT_ID_LENGTH] for name, id_ in state["x"].items()}
            value = signing.dumps({"x": short}, salt=COOKIE_SALT, compress=True)
        if state:
            response.set_cookie(
                cookie_name(study), value,
                max_age=COOKIE_AGE_S, secure=settings.SESSION_COOKIE_SECURE, httponly=True,
                samesite="Lax",
            )
        else:
            response.delete_cookie(cookie_name(study), samesite="Lax")
    return response


def token_from_cookie(value: str) -> str | None:
    """Return the participant token in a study cookie's value (for tests and tools)."""
    return signing.loads(value, salt=COOKIE_SALT).get("p")


def external_ids_from(query) -> dict:
    """Return the crowd-platform parameters of the entry link (printable characters only)."""
    # Control characters (a NUL byte above all, which PostgreSQL refuses in text) are
    # never part of a platform's ids: drop them rather than fail.
    clean = {
        name: "".join(c for c in query.get(name, "") if c.isprintable())
        for name in EXTERNAL_PARAMS
    }
    return {name: value[:MAX_ID_LENGTH] for name, value in clean.items() if value.strip()}


def browser_participant(request, study):
    """Return the participant of this browser (read with ``by_token``), or None."""
    token = browser_state(request, study).get("p")
    if not token:
        return None
    participant = Participant.objects.by_token(study, token)
    if participant is not None:
        participant.study = study  # already read: spare the query
    return participant


def trial_with_items(participant, trial_id):
    """Return ``(trial, items)`` of one of the participant's trials, read in one query
    (items in screen order, with their stimuli), or ``(None, [])``."""
    items = list(
        TrialItem.objects.filter(trial_id=trial_id, trial__participant=participant)
        .select_related("trial", "stimulus")
        .order_by("position")
    )
    if not items:
        return None, []
    trial = items[0].trial
    trial.participant = participant
    for item in items:
        item.trial = trial
    return trial, items


def remember(request, participant) -> None:
    set_browser_state(request, participant.study, {"p": participant.token})


def unavailable(request, study, reason: str, status: int = 200):
    context = {"study": study, "reason": reason}
    return render(request, "survey/unavailable.html", context, status=status)


def bad_answer(request, study, messages: list[str]):
    context = {"study": study, "messages": messages, "back": page_url(study, "trial")}
    return render(request, "survey/bad_answer.html", context, status=400)


def page_url(study, name: str) -> str:
    return reverse("survey:page", args=[study.slug, name])


def render_trial(request, study, trial, items, number, total, **extra):
    """Render a trial page; ``number`` is None for a practice trial.

    Shared by participants and the researcher's preview (which passes unsaved trials).
    """
    for item in items:
        item.label = study.kind.item_label(item.position)
    context = {
        "study": study,
        "trial": trial,
        "items": items,
        "number": number,
        "total": total,
        "progress": round(100 * ((number or 1) - 1) / max(total, 1)),
        "ranks": range(1, len(items) + 1),
        "scripts": study.kind.scripts,
        "page": "trial",
        "trial_key": trial.pk,
        "action_name": trial.action.replace("_", " "),
        **extra,
    }
    context.update(study.kind.trial_context(trial, items))
    return render(request, study.kind.trial_template, context)


class Page:
    """One step of the sequence; subclasses say when it is done and what it does."""

    name = ""
    template_name = ""

    def is_done(self, participant) -> bool:
        raise NotImplementedError

    def context(self, request, study, participant) -> dict:
        return {}

    def get(self, request, study, participant):
        context = {"study": study, "participant": participant, "page": self.name}
        context.update(self.context(request, study, participant))
        return render(request, self.template_name, context)

    def post(self, request, study, participant):
        return redirect(page_url(study, current_page(participant).name))


class Consent(Page):
    name = "consent"
    template_name = "survey/consent.html"

    def is_done(self, participant):
        return participant is not None and participant.consented_at is not None

    def context(self, request, study, participant):
        return {"form": ConsentForm()}

    def post(self, request, study, participant):
        form = ConsentForm(request.POST)
        if not form.is_valid():
            return render(request, self.template_name, {"study": study, "form": form})
        external = browser_state(request, study).get("x", {})
        try:
            participant = Participant.objects.enroll(
                study, external, request.headers.get("User-Agent", "")
            )
        except Unavailable as exc:
            return unavailable(request, study, exc.reason)
        remember(request, participant)
        return super().post(request, study, participant)


class Instructions(Page):
    name = "instructions"
    template_name = "survey/instructions.html"

    def is_done(self, participant):
        return participant.has_trials()

    def post(self, request, study, participant):
        Participant.objects.start(participant)
        participant.n_trials = participant.trials.count()
        if not participant.n_trials:
            return unavailable(request, study, "closed")
        return super().post(request, study, participant)


class Trials(Page):
    name = "trial"

    def is_done(self, participant):
        return participant.completed_at is not None

    def get(self, request, study, participant):
        trial, items = trial_with_items(participant, participant.current_id)
        if trial is None:  # no unanswered trial with clips: broken data, not the person's fault
            log.error("participant %s of %s: no trial to show (current %s)",
                      participant.pk, study.slug, participant.current_id)
            return unavailable(request, study, "broken", status=500)
        Trial.objects.mark_shown(trial)
        practice = participant.n_practice
        total = participant.n_trials - practice
        number = None if trial.kind == Trial.Kind.PRACTICE else trial.index + 1 - practice
        return render_trial(
            request, study, trial, items, number, total, practice_over=practice and number == 1
        )

    def post(self, request, study, participant):
        trial_id = request.POST.get("trial", "")
        if not (trial_id.isascii() and trial_id.isdigit() and len(trial_id) <= 18):
            return bad_answer(request, study, ["The answer does not say which question it is for."])
        trial, items = trial_with_items(participant, int(trial_id))
        if trial is None:
            return bad_answer(request, study, ["This question is not part of your session."])
        if trial.answered_at is not None:
            return super().post(request, study, participant)  # a repeated submit: move on
        # ``current_id`` was read before ``trial``: an unanswered trial that is not the
        # current one is not for now (a simultaneous copy of this submit is settled by
        # ``record_answer``, which stores one and tells the other).
        if trial.pk != participant.current_id:
            return bad_answer(request, study, ["This is not the question you are on."])
        form = study.kind.answer_form(trial, items, request.POST)
        if not form.is_valid():
            return bad_answer(request, study, form.messages())
        if not Trial.objects.record_answer(trial, form.answers(), form.trial_answer(), items=items):
            # A simultaneous copy stored it, and may have completed the study meanwhile.
            participant.refresh_from_db(fields=["completed_at"])
        return super().post(request, study, participant)


class Demographics(Page):
    name = "about-you"
    template_name = "survey/demographics.html"

    def is_done(self, participant):
        return not participant.study.ask_demographics or participant.demographics is not None

    def context(self, request, study, participant):
        return {"form": DemographicsForm()}

    def post(self, request, study, participant):
        form = DemographicsForm(request.POST)
        if not form.is_valid():
            context = {"study": study, "participant": participant, "form": form}
            return render(request, self.template_name, context, status=400)
        Participant.objects.record_demographics(participant, form.cleaned_data)
        return super().post(request, study, participant)


class Completion(Page):
    name = "done"
    template_name = "survey/done.html"

    def is_done(self, participant):
        return False


PAGE_SEQUENCE = [Consent(), Instructions(), Trials(), Demographics(), Completion()]
PAGES = {page.name: page for page in PAGE_SEQUENCE}


def current_page(participant) -> Page:
    """Return the first page of the sequence the participant has not finished."""
    for page in PAGE_SEQUENCE:
        if participant is None or not page.is_done(participant):
            return page
    return PAGE_SEQUENCE[-1]


def enter(request, study):
    """Start or resume a participant from the study link; return the redirect."""
    external = external_ids_from(request.GET)
    participant = browser_participant(request, study)
    if participant is not None and external_key(external) not in ("", participant.external_key):
        participant = None  # another person on the same browser
    if participant is None:
        participant = Participant.objects.find(study, external)
        taken = participant is not None and participant.completed_at is not None
        if participant is None or taken:
            # Consent re-checks these ids, so skipping this page changes nothing.
            set_browser_state(request, study, {"x": external})
            if taken:
                return unavailable(request, study, "taken")
            if study.status != Study.Status.OPEN:
                return unavailable(request, study, "closed")
            if study.is_full():
                return unavailable(request, study, "full")
    if participant is not None:
        remember(request, participant)
    return redirect(page_url(study, current_page(participant).name))


def show(request, study, name: str):
    """Render or submit page ``name``, or redirect to the page the participant is on."""
    participant = browser_participant(request, study)
    page = current_page(participant)
    if name != page.name:
        return redirect(page_url(study, page.name))
    if participant is None and study.status != Study.Status.OPEN:
        return unavailable(request, study, "closed")
    if request.method == "POST":
        return page.post(request, study, participant)
    return page.get(request, study, participant)
