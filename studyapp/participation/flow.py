"""A participant's path through a study, declared once as data (as in oTree).

``PAGE_SEQUENCE`` lists the pages; the participant is always sent to the first page
they have not finished, so a reload, a back button or a stale tab lands where they are.
The same sequence drives three things: real participants (:class:`DatabaseStore`, found
through a signed per-study cookie, no session row), the researcher's preview
(:class:`~studyapp.participation.preview.PreviewStore`: the same pages over a store that keeps
nothing) and simulated participants (each page knows how a bot fills it in:
:meth:`Page.bot_fill`, used by :mod:`studyapp.participation.bots`).

The server decides whether a trial's clips were watched: an answer is taken only once
every clip the trial shows was fetched to its end from this server and the clips'
playing time has passed since the trial page was served. It also decides who holds a
place: a participant past the study's time limit, or idle (no answer) past its idle
limit, gets the timed-out page on every later request (:meth:`Participant.timed_out`).
"""

from __future__ import annotations

import logging

from django.conf import settings
from django.core import signing
from django.shortcuts import redirect, render
from django.db import transaction
from django.urls import reverse
from django.utils import timezone

from studyapp.crowd.platform import EntryRefused
from studyapp.participation import fetch_log
from studyapp.participation.answers import TrialForm, field_name
from studyapp.participation.forms import ConsentForm, DemographicsForm
from studyapp.stimuli import media
from studyapp.survey.models import Participant, Study, Trial, TrialItem, Unavailable

# Browsers drop cookies over 4 KB; crowd ids are short, so longer ones are cut further.
MAX_COOKIE_BYTES = 3000
SHORT_ID_LENGTH = 30
COOKIE_SALT = "studyapp.survey.participant"
COOKIE_AGE_S = 60 * 60 * 24 * 30
# A trial form posting this field gets the next trial in the answer's response (no
# redirect); without it the answer is followed by a redirect to the page to show.
INLINE_FIELD = "next"

log = logging.getLogger(__name__)


# --- the browser's cookie of a study -------------------------------------------------


def cookie_name(study) -> str:
    return f"study{study.pk}"


def browser_state(request, study) -> dict:
    """Return what this browser's cookie says about ``study``: ``{"p": token}`` for a
    participant, ``{"x": {...}, "k": key}`` for the platform ids of someone not yet
    consenting, or ``{}`` (no cookie, or one that was not signed here)."""
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
            value = signing.dumps({"x": short, "k": state.get("k", "")[:2 * SHORT_ID_LENGTH]},
                                  salt=COOKIE_SALT, compress=True)
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


# --- stores: where a participant's progress is kept -------------------------------------


class DatabaseStore:
    """Real participants: everything is stored, clips are served under item tokens."""

    preview = False

    def url(self, study, name: str) -> str:
        return reverse("survey:page", args=[study.slug, name])

    def participant(self, request, study):
        """Return the participant of this browser (read with ``by_token``), or None."""
        for _ in range(2):
            token = browser_state(request, study).get("p")  # the cookie of study.pk
            participant = Participant.objects.by_token(study, token) if token else None
            # ``study`` may be the row as this process kept it: by_token read its version.
            kept_pk = study.pk
            Study.objects.current(study, participant.study_version if participant else None)
            if study.pk == kept_pk:
                break  # else the slug's study was made anew: read its cookie
        if participant is not None:
            participant.study = study  # already read: spare the query
        return participant

    def pending_ids(self, request, study) -> tuple[dict, str]:
        state = browser_state(request, study)
        return state.get("x", {}), state.get("k", "")

    def enroll(self, request, study, outcome: str = ""):
        ids, key = self.pending_ids(request, study)
        platform = study.platform
        if not key and (platform.require_id or platform.strict_ids):
            raise Unavailable("no_id")  # the consent page was posted without the entry link
        participant = Participant.objects.enroll(
            study, ids, key, request.headers.get("User-Agent", ""), outcome=outcome
        )
        set_browser_state(request, study, {"p": participant.token})
        participant.study = study
        return participant

    def start(self, request, participant) -> None:
        participant.n_trials = Participant.objects.start(participant)

    def current_trial(self, request, participant):
        """Return ``(trial, items, number, total)`` of the first unanswered trial."""
        trial, items = (getattr(participant, "next_trial", None)
                        or self.trial_with_items(participant, participant.current_id))
        if trial is None:
            return None, [], None, 0
        self.write_ahead(participant.study, items)
        Trial.objects.mark_shown(trial)
        practice = participant.n_practice
        total = participant.n_trials - practice
        number = None if trial.kind == Trial.Kind.PRACTICE else trial.index + 1 - practice
        return trial, items, number, total

    @staticmethod
    def trial_with_items(participant, trial_id):
        """Return ``(trial, items)`` of one of the participant's trials, read in one query
        (items in screen order, with their stimuli), or ``(None, [])``."""
        found = TrialItem.objects.trials_of(participant, trial_id)
        return found[0] if found else (None, [])

    def advance(self, participant, trial) -> bool:
        """After ``trial`` was answered, take the next trial and its items for
        ``current_trial``: read with the answered one (``posted_trial``; trials are
        answered in index order, so it is the next index); return False when there is
        none to show now (the caller redirects instead)."""
        following = getattr(participant, "following", None)
        if not following or following[0].index != trial.index + 1:
            return False
        participant.current_id = following[0].pk
        participant.next_trial = following
        return True

    def posted_trial(self, request, participant):
        """Return ``(trial, items, problem)`` of the trial a POST answers; the unanswered
        trial after it is read in the same statement (``participant.following``)."""
        trial_id = request.POST.get("trial", "")
        if not (trial_id.isascii() and trial_id.isdigit() and len(trial_id) <= 18):
            return None, [], "The answer does not say which question it is for."
        found = TrialItem.objects.trials_of(participant, int(trial_id), and_next=True)
        if not found or found[0][0].pk != int(trial_id):
            return None, [], "This question is not part of your session."
        trial, items = found[0]
        participant.following = found[1] if len(found) > 1 else None
        if trial.answered_at is not None:
            return trial, items, None
        # ``current_id`` was read before ``trial``: an unanswered trial that is not the
        # current one is not for now (a simultaneous copy of this submit is settled by
        # ``record_answer``, which stores one and tells the other).
        if trial.pk != participant.current_id:
            return None, [], "This is not the question you are on."
        return trial, items, None

    def clip_url(self, item, ext="mp4") -> str:
        return item.clip_url(ext)

    @staticmethod
    def write_ahead(study, items) -> None:
        """Behind nginx with the media on this machine, write the delivery files the trial
        page makes the browser fetch, so nginx sends them without asking a worker
        (media.deliver_ahead): each clip's payload where the page plays one, else its
        video, and its poster. Done before the trial is marked shown, so the time of a
        write is not counted as the participant's."""
        if not media.writes_ahead():
            return
        player = page_player(study, items)
        for item in items:
            media.deliver_ahead(item.stimulus, item.token, "motion" if player else "mp4")
            if item.stimulus.poster:
                media.deliver_ahead(item.stimulus, item.token, "png")

    def watch_problems(self, trial, items, labels) -> list[str]:
        """Return why the server cannot take an answer yet: clips not fetched to their
        end, or the clips' playing time not yet passed since the page was served."""
        if trial.shown_at is None:
            return ["This question's page was never opened; open it and watch its clips."]
        # A fetch whose database record still waits for the write lock has a witness.
        fetch_log.witness([item for item in items if item.required])
        problems = [f"{labels[item.pk]} has not been loaded to its end yet: let it play "
                    f"through, then answer."
                    for item in items if item.required and item.fetched_at is None]
        needed = max((item.stimulus.duration for item in items if item.required), default=0)
        needed *= settings.STUDY_WATCH_TIME_FACTOR
        elapsed = (timezone.now() - trial.shown_at).total_seconds()
        if elapsed < needed:
            problems.append(
                f"This answer came {elapsed:.1f} s after the question opened, before its clips "
                f"could play through ({needed:.1f} s). Watch every clip to the end, then answer."
            )
        return problems

    def record_answer(self, request, trial, answer, items) -> bool:
        with transaction.atomic():  # the fetches the check read from witnesses, with it
            won = Trial.objects.record_answer(trial, answer, items, fetches=fetch_log.merged)
            if not won:
                fetch_log.settle(items)
        if not won:  # a simultaneous copy stored it, and may have completed the study
            trial.participant.refresh_from_db(fields=["completed_at", "outcome",
                                                      "completion_code"])
        return won

    def record_demographics(self, request, participant, answers) -> None:
        Participant.objects.record_demographics(participant, answers)

    def timed_out(self, participant) -> bool:
        if not participant.timed_out():
            return False
        # A kept study row's minutes (a default time limit's source) can be up to
        # MINUTES_KEPT_S old: the outcome is stored for good only if the study as it
        # stands now times the participant out too.
        kept = participant.study
        participant.study = Study.objects.get(pk=kept.pk)
        try:
            if not participant.timed_out():
                return False
        finally:
            participant.study = kept
        Participant.objects.mark_timed_out(participant)
        return True


# --- pages -----------------------------------------------------------------------------


def unavailable(request, study, reason: str, status: int = 200, detail: str = ""):
    context = {"study": study, "reason": reason, "detail": detail}
    return render(request, "survey/unavailable.html", context, status=status)


def bad_answer(request, store, study, messages: list[str]):
    context = {"study": study, "messages": messages, "back": store.url(study, "trial"),
               "preview": store.preview}
    return render(request, "survey/bad_answer.html", context, status=400)


class Page:
    """One step of the sequence; subclasses say when it is done, what it does, and how a
    bot fills it in."""

    name = ""
    template_name = ""

    def is_done(self, participant) -> bool:
        raise NotImplementedError

    def context(self, request, store, study, participant) -> dict:
        return {}

    def get(self, request, store, study, participant):
        context = {"study": study, "participant": participant, "page": self.name,
                   "preview": store.preview}
        context.update(self.context(request, store, study, participant))
        return render(request, self.template_name, context)

    def post(self, request, store, study, participant):
        return redirect(store.url(study, current_page(participant).name))

    def bot_fill(self, fields: dict, form: dict, bot) -> dict:
        """Return what a bot posts on this page, given the form's fields as read."""
        return fields


class Consent(Page):
    name = "consent"
    template_name = "survey/consent.html"

    def is_done(self, participant):
        return participant is not None and (
            participant.consented_at is not None or participant.is_finished()
        )

    def context(self, request, store, study, participant):
        return {"form": ConsentForm(study=study)}

    def post(self, request, store, study, participant):
        form = ConsentForm(request.POST, study=study)
        if not form.is_valid():
            context = {"study": study, "form": form, "preview": store.preview}
            return render(request, self.template_name, context, status=400)
        try:
            participant = store.enroll(request, study, outcome=form.outcome())
        except Unavailable as exc:
            detail = {"no_id": study.platform.id_params[0],
                      "session_taken": study.platform.session_param}.get(exc.reason, "")
            return unavailable(request, study, exc.reason, detail=detail)
        return super().post(request, store, study, participant)

    def bot_fill(self, fields, form, bot):
        return fields | bot.consent(form)


class Instructions(Page):
    name = "instructions"
    template_name = "survey/instructions.html"

    def is_done(self, participant):
        return participant.is_finished() or participant.has_trials()

    def post(self, request, store, study, participant):
        store.start(request, participant)
        if not participant.n_trials:
            return unavailable(request, study, "closed")
        return super().post(request, store, study, participant)


class Trials(Page):
    name = "trial"

    def is_done(self, participant):
        return participant.is_finished()

    def get(self, request, store, study, participant):
        trial, items, number, total = store.current_trial(request, participant)
        if trial is None:  # no unanswered trial with clips: broken data, not the person's fault
            log.error("participant %s of %s: no trial to show", participant.pk, study.slug)
            return unavailable(request, study, "broken", status=500)
        return render_trial(request, store, study, trial, items, number, total,
                            participant.n_practice)

    def post(self, request, store, study, participant):
        trial, items, problem = store.posted_trial(request, participant)
        if problem:
            return bad_answer(request, store, study, [problem])
        if trial.answered_at is not None:
            return super().post(request, store, study, participant)  # a repeated submit
        form = TrialForm(study, trial, items, request.POST)
        if not form.is_valid():
            return bad_answer(request, store, study, form.messages())
        labels = {item.pk: shown_label(study, item) for item in items}
        problems = store.watch_problems(trial, items, labels)
        if problems:
            return bad_answer(request, store, study, problems)
        store.record_answer(request, trial, form.answer(), items)
        # One request per answer: a page that asks for it (the trial form does) gets the
        # next trial in this response, rather than a redirect and a second request.
        if (request.POST.get(INLINE_FIELD) and current_page(participant) is self
                and store.advance(participant, trial)):
            return self.get(request, store, study, participant)
        return super().post(request, store, study, participant)

    def bot_fill(self, fields, form, bot):
        return fields | bot.answer_trial(fields, form)


class Demographics(Page):
    name = "about-you"
    template_name = "survey/demographics.html"

    def is_done(self, participant):
        return (not participant.study.ask_demographics or participant.demographics is not None
                or participant.outcome not in ("", Participant.Outcome.COMPLETED,
                                               Participant.Outcome.FAILED_ATTENTION))

    def context(self, request, store, study, participant):
        return {"form": DemographicsForm()}

    def post(self, request, store, study, participant):
        form = DemographicsForm(request.POST)
        if not form.is_valid():
            context = {"study": study, "participant": participant, "form": form,
                       "preview": store.preview}
            return render(request, self.template_name, context, status=400)
        store.record_demographics(request, participant, form.cleaned_data)
        return super().post(request, store, study, participant)

    def bot_fill(self, fields, form, bot):
        return fields | bot.about_me()


class Completion(Page):
    name = "done"
    template_name = "survey/done.html"

    def is_done(self, participant):
        return False

    def context(self, request, store, study, participant):
        return {"exit_url": study.platform.completion_url(participant),
                "outcome": participant.outcome}


PAGE_SEQUENCE = [Consent(), Instructions(), Trials(), Demographics(), Completion()]
PAGES = {page.name: page for page in PAGE_SEQUENCE}


def current_page(participant) -> Page:
    """Return the first page of the sequence the participant has not finished."""
    for page in PAGE_SEQUENCE:
        if participant is None or not page.is_done(participant):
            return page
    return PAGE_SEQUENCE[-1]


# --- the trial page ------------------------------------------------------------------


def shown_label(study, item) -> str:
    """Return the name a participant sees for any item of a trial."""
    if item.role == TrialItem.Role.REFERENCE:
        return "The reference clip"
    if item.role == TrialItem.Role.EXAMPLE:
        return "An example clip of the scoring standard"
    return study.kind.item_label(item)


class Question:
    """One criterion of a trial page: its words and the field names of its answers."""

    def __init__(self, kind, index, criterion, judged):
        self.index, self.key, self.text = index, criterion.key, criterion.text
        self.rows = [
            (item, field_name(f"{kind.item_prefix}_{item.token}", index, criterion))
            for item in judged
        ] if kind.item_prefix else [(item, "") for item in judged]
        self.trial_name = field_name(kind.trial_answer, index, criterion) if kind.trial_answer else ""


def page_player(study, items) -> str:
    """Return the in-page player of a trial page: the study's, when every clip has its
    payload (the mp4 stays the fallback where WebGL 2 is missing), else ""."""
    return study.player if all(item.stimulus.motion for item in items) else ""


def render_trial(request, store, study, trial, items, number, total, n_practice, **extra):
    """Render a trial page; ``number`` is None for a practice trial."""
    kind = study.kind
    player = page_player(study, items)
    for item in items:
        item.label = shown_label(study, item)
        item.url = store.clip_url(item)
        item.poster_url = store.clip_url(item, "png") if item.stimulus.poster else ""
        item.motion_url = store.clip_url(item, "motion") if player else ""
    judged = [item for item in items if item.role == TrialItem.Role.JUDGED]
    criteria = kind.criteria(study)
    context = {
        "study": study,
        "trial": trial,
        "items": judged,
        "questions": [Question(kind, i, c, judged) for i, c in enumerate(criteria)],
        "several_questions": len(criteria) > 1,
        "number": number,
        "total": total,
        "progress": round(100 * ((number or 1) - 1) / max(total, 1)),
        "scripts": kind.scripts,
        "page": "trial",
        "trial_key": trial.pk if not store.preview else trial.index,
        "action_name": trial.action.replace("_", " "),
        "prompt": trial.prompt,
        "practice_over": bool(n_practice) and number == 1,
        "preview": store.preview,
        "player": player,
        # What the clip and check templates ask for where a type leaves it out (a name
        # missing from the context costs the template engine two exceptions a lookup).
        "instruction": "", "lazy": False, "hold": False, "caption": "",
        **extra,
    }
    if trial.kind == Trial.Kind.INSTRUCTED:
        context["instruction"] = kind.instruction_sentence(study, trial, judged)
    context.update(kind.trial_context(study, trial, items))
    return render(request, kind.template_name(), context)


# --- entry and dispatch ------------------------------------------------------------------


def enter(request, study, store=None):
    """Start or resume a participant from the study link; return the redirect."""
    store = store or DatabaseStore()
    participant = store.participant(request, study)  # first: it checks a kept study row
    try:
        ids, key = study.platform.read_ids(request.GET)
    except EntryRefused as refused:
        return unavailable(request, study, refused.reason, status=400, detail=refused.detail)
    if participant is not None and key not in ("", participant.external_key):
        if study.platform.strict_ids and not store.preview:
            # This browser took part under another id: a made-up id to start again.
            return unavailable(request, study, "other_id", status=403)
        participant = None  # another person on the same browser
    if participant is None:
        participant = Participant.objects.find(study, key)
        if participant is not None:
            participant.study = study
            set_browser_state(request, study, {"p": participant.token})
    if participant is None:
        # Consent re-checks these ids, so skipping this page changes nothing.
        set_browser_state(request, study, {"x": ids, "k": key})
        if study.status != Study.Status.OPEN:
            return unavailable(request, study, "closed")
        if Participant.objects.sharing_ids(study, ids, key):
            return unavailable(request, study, "session_taken", status=403,
                               detail=study.platform.session_param)
        if study.is_full():
            return unavailable(request, study, "full")
    elif store.timed_out(participant):
        return unavailable(request, study, "timed_out")
    return redirect(store.url(study, current_page(participant).name))


def show(request, study, name: str, store=None):
    """Render or submit page ``name``, or redirect to the page the participant is on."""
    store = store or DatabaseStore()
    participant = store.participant(request, study)
    if participant is not None and store.timed_out(participant):
        return unavailable(request, study, "timed_out", status=410)
    page = current_page(participant)
    if name != page.name:
        return redirect(store.url(study, page.name))
    if participant is None and study.status != Study.Status.OPEN and not store.preview:
        return unavailable(request, study, "closed")
    if request.method == "POST":
        return page.post(request, store, study, participant)
    return page.get(request, store, study, participant)
