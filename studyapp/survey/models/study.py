"""A study: its type, options, texts, places, crowd settings and duration."""

import copy
import secrets
import threading
import time
from datetime import timedelta

from django.apps import apps
from django.core.exceptions import ValidationError
from django.db import connection, models
from django.db.transaction import TransactionManagementError
from django.db.models import Count, F, OuterRef, Subquery
from django.db.models.functions import Coalesce
from django.urls import reverse

from studyapp.crowd.platform import outcomes_of, platform_of
from studyapp.participation.duration import Duration, fixed_seconds, study_duration
from studyapp.survey.models.rows import Columns, Statements, Values, quote, read
from studyapp.survey.study_type_registry import STUDY_TYPES


def new_token() -> str:
    """Return an opaque, unguessable URL token.

    It never starts with ``-`` or ``_``: in an exported CSV a spreadsheet would run a
    cell starting with ``-`` as a formula, so the export would have to prefix it and the
    token would no longer read back as itself.
    """
    while True:
        token = secrets.token_urlsafe(16)
        if token[0].isalnum():
            return token


def model(name: str):
    """Return the ``survey`` model called ``name`` from Django's app registry.

    A study counts its participants and trials, whose module imports this one; asking the
    registry keeps the imports pointing one way."""
    return apps.get_model("survey", name)


def study_type_choices():
    """Return the registered study types as field choices."""
    return [(name, kind.label) for name, kind in STUDY_TYPES.items()]


class Unavailable(Exception):
    """The study cannot take this participant; ``reason`` picks the page shown."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def _count(queryset, group: str):
    """Return a subquery counting ``queryset`` rows per ``group`` (0 when none)."""
    counted = queryset.order_by().values(group).annotate(n=Count("pk")).values("n")
    return Coalesce(Subquery(counted[:1]), 0)


def new_version() -> int:
    """Return the first ``Study.version`` of a row: random, so a study made again under a
    slug (or a reused id) does not match a copy a process kept of the one before."""
    return secrets.randbits(40)


# The process's copies of study rows by slug (``StudyManager.cached``).
_CACHE: dict[str, "Study"] = {}
_CACHE_LOCK = threading.Lock()
# Seconds a kept row's session length (``Study.minutes``) is used before it is worked out
# again: it plans a session and reads every completion, and a participant's pages ask for
# it (the consent text, the time limit on every request of a Prolific study).
MINUTES_KEPT_S = 30.0


class StudyManager(models.Manager):
    def cached(self, slug: str) -> "Study":
        """Return the study ``slug`` as this process last read it, unchecked (a copy of its
        own for the request), or read it now; Study.DoesNotExist when there is none.

        Every participant page reads the study, so each process keeps the row; the page
        then checks it against the row's ``version`` in a statement it runs anyway
        (``Participant.objects.by_token``), or with :meth:`current` where it runs none.
        Any UPDATE of the row, on any node, moves ``version`` on, so no process keeps
        serving a changed study (on SQLite ``lock``'s no-op UPDATE does too: each start
        there makes processes read the row again, which costs a read, nothing more).
        """
        study = _CACHE.get(slug)
        if study is None:
            return self.remember(self.get(slug=slug))
        return copy.copy(study)

    def remember(self, study: "Study") -> "Study":
        """Keep a copy of ``study`` (just read) for ``cached``; return ``study``."""
        kept = copy.copy(study)
        # What the process works out from the row, shared by the copies ``cached`` hands
        # out (a shallow copy shares this dict): see ``Study.minutes``.
        kept.__dict__["_worked_out"] = {}
        with _CACHE_LOCK:
            if len(_CACHE) > 1000:
                _CACHE.clear()
            _CACHE[study.slug] = kept
        return study

    def current(self, study: "Study", version=None) -> "Study":
        """Make ``study`` (from ``cached``) the stored row, in place, and return it.

        ``version`` is the row's as read with the participant (same id); None: read the
        id and version of the row of ``study.slug`` now (a study deleted and made again
        under the slug has another id). Study.DoesNotExist when the slug names none.
        """
        slug = study.slug
        if version is None:
            found = read(_VERSION.get(), [slug], Values(2))
            row = found[0][0] if found else None
            if row is None:
                _CACHE.pop(slug, None)
                raise self.model.DoesNotExist(f"no study {slug!r}")
            stale = row != (study.pk, study.version)
        else:
            stale = version != study.version
        if stale:
            _CACHE.pop(slug, None)
            fresh = self.get(slug=slug)
            study.__dict__.update(fresh.__dict__)
            self.remember(study)
        return study

    def create_study(self, study_type: str, slug: str, title: str, **fields) -> "Study":
        """Create a study of a registered type, filling in its default texts and options."""
        kind = STUDY_TYPES.get(study_type)()
        fields.setdefault("clips_per_trial", kind.default_clips_per_trial)
        fields["options"] = kind.check_options(fields.get("options") or {})
        study = self.model(study_type=study_type, slug=slug, title=title, **fields)
        study.instructions = study.instructions or kind.default_instructions(study)
        study.full_clean()
        study.save()
        return study

    def with_counts(self):
        """Annotate participants started/completed and answered judgements."""
        Participant, Trial, TrialItem = model("Participant"), model("Trial"), model("TrialItem")
        participants = Participant.objects.filter(study=OuterRef("pk"))
        judgements = TrialItem.objects.judged().filter(
            trial__participant__study=OuterRef("pk"), trial__answered_at__isnull=False
        )
        return self.annotate(
            n_started=_count(participants.exclude(consented_at=None), "study"),
            n_completed=_count(participants.filter(completed_at__isnull=False), "study"),
            n_judgements=_count(
                judgements.exclude(trial__kind=Trial.Kind.PRACTICE), "trial__participant__study"
            ),
            n_excluded=_count(
                participants.filter(outcome=Participant.Outcome.FAILED_ATTENTION), "study"
            ),
        )

    def lock(self, study_id: int) -> "Study":
        """Return the study row locked until the end of the current transaction (its
        minutes worked out at most once while it is held).

        PostgreSQL takes a row lock (FOR UPDATE). SQLite ignores FOR UPDATE, so a no-op
        UPDATE takes its database write lock first: concurrent assigners then queue
        instead of reading the same counts.
        """
        if connection.get_autocommit():  # as select_for_update: a lock would be held for nothing
            raise TransactionManagementError("Study.objects.lock needs a transaction")
        if connection.vendor == "sqlite":
            self.filter(pk=study_id).update(status=F("status"))
        found = read(_LOCK.get(), [study_id], STUDY_ROW)  # written out: every entry locks twice
        if not found:
            raise self.model.DoesNotExist(f"no study with id {study_id}")
        study = found[0][0]
        # Its minutes (a session planned, every completion read: a Prolific study's default
        # time limit) are worked out once for the transaction, not at each place-count.
        study.__dict__["_worked_out"] = {}
        return study


class Study(models.Model):
    class Status(models.TextChoices):
        DRAFT = "draft", "Draft"
        OPEN = "open", "Open"
        CLOSED = "closed", "Closed"

    slug = models.SlugField(unique=True)
    title = models.CharField(max_length=200, help_text="Shown to participants: name no method.")
    study_type = models.CharField(max_length=32, choices=study_type_choices, default="ranking")
    status = models.CharField(max_length=16, choices=Status.choices, default=Status.OPEN)
    dataset = models.CharField(max_length=64, blank=True)
    data_note = models.CharField(
        max_length=300, blank=True, help_text="Shown to participants, e.g. that data is synthetic."
    )
    clips_per_trial = models.PositiveSmallIntegerField(default=6)
    trials_per_participant = models.PositiveSmallIntegerField(
        null=True, blank=True, help_text="Main trials per participant; blank: the type's default."
    )
    practice = models.BooleanField(
        default=False, help_text="Start with a practice trial whose answer is not a judgement."
    )
    catch_trials = models.PositiveSmallIntegerField(
        default=0, help_text="Trials per participant with a broken clip (stimuli marked catch)."
    )
    instructed_checks = models.PositiveSmallIntegerField(
        default=0, help_text="Trials per participant whose text says which answer to give "
        "(instructed-response attention checks)."
    )
    max_failed_catch = models.PositiveSmallIntegerField(
        default=1, help_text="More failed attention checks (catch and instructed trials) than "
        "this: the outcome is a failed attention check (its own completion code). 1: a "
        "participant fails after two, as Prolific allows."
    )
    repeat_trials = models.PositiveSmallIntegerField(
        default=0, help_text="Main trials shown again later, to measure consistency."
    )
    design = models.CharField(
        max_length=16, choices=[("balanced", "Balanced"), ("adaptive", "Adaptive")],
        default="balanced", help_text="How main trials choose their sources: balanced counts, or "
        "adaptive (types with a worth model: pairs where the most is learnt about the order; "
        "see README, 'Adaptive studies').",
    )
    adaptive = models.JSONField(
        default=dict, blank=True, help_text='Settings of an adaptive design, e.g. {"every": 50, '
        '"min_showings": 2, "target": "order"} (or "top_two", or {"versus": "mine"}).',
    )
    sampling = models.JSONField(
        default=dict, blank=True, editable=False,
        help_text="The adaptive design's sampling distribution over pairs of sources, "
        "recomputed in the background every few answers.",
    )
    arena = models.JSONField(
        default=dict, blank=True, help_text='An arena\'s settings (a standing adaptive study to '
        'which sources are added later), e.g. {"min_votes": 30, "real": "real", "baseline": '
        '"mdm"}; empty: not an arena. See README, "Arena".',
    )
    arena_state = models.JSONField(
        default=dict, blank=True, editable=False,
        help_text="What changes while an arena stands: sources added and retired, and its "
        "leaderboard as last computed.",
    )
    stop_when = models.JSONField(
        default=dict, blank=True, help_text='A stopping rule, checked in the background every few '
        'answers: {"interval_width": 0.6} (the widest interval of the target\'s differences), '
        '{"rank_certainty": 0.95} or {"judgements": 2000} (answered main trials), or several '
        '(the first met stops); see README, "Stopping rules".',
    )
    stopped = models.JSONField(
        default=dict, blank=True, editable=False,
        help_text="How the study stopped by its stopping rule (empty while it runs).",
    )
    ask_demographics = models.BooleanField(
        default=False, help_text="Ask age range, gender and comments (all optional) at the end."
    )
    options = models.JSONField(
        default=dict, blank=True, help_text="The study type's own options (see README)."
    )
    criteria = models.JSONField(
        default=list, blank=True,
        help_text='Questions asked of the same clips, e.g. [{"key": "naturalness", "question": '
        '"..."}, {"key": "fit", "question": "..."}]; empty: the type\'s one question.',
    )
    crowd = models.JSONField(
        default=dict, blank=True,
        help_text='Crowd platform: {"platform": "prolific", "codes": {"completed": ..., '
        '"failed_attention": ..., "no_consent": ..., "screened_out": ...}, '
        '"time_limit_minutes": 30, "idle_minutes": 10}; see README, "Crowd platforms".',
    )
    instructions = models.TextField(blank=True)
    consent_text = models.TextField(blank=True)
    completion_url = models.URLField(
        blank=True, help_text="Where to send participants at the end (studies without a platform)."
    )
    max_participants = models.PositiveIntegerField(
        null=True, blank=True, help_text="Finished and active participants at most."
    )
    player = models.CharField(
        max_length=8, blank=True,
        help_text="The figure the in-page player (WebGL) draws where the browser can, the mp4 "
        "otherwise (the style's player_figure, e.g. stick or body); blank: the mp4 only. Needs "
        "clips built with render.player: webgl.",
    )
    created_at = models.DateTimeField(auto_now_add=True)
    # Random when the row is made, and one more on every UPDATE of it, whoever runs it (a
    # database trigger: migration 0013), so processes that keep the row
    # (StudyManager.cached) see that it changed, on every node.
    version = models.BigIntegerField(default=new_version, editable=False)

    objects = StudyManager()

    class Meta:
        verbose_name_plural = "studies"
        ordering = ["-created_at"]

    def __str__(self):
        return self.slug

    def get_absolute_url(self):
        return reverse("survey:entry", args=[self.slug])

    @property
    def kind(self):
        """Return this study's registered type (its trials, form and template)."""
        return STUDY_TYPES.get(self.study_type)()

    @property
    def platform(self):
        """Return this study's crowd platform adapter (:mod:`studyapp.crowd.platform`)."""
        return platform_of(self)

    def clean(self):
        try:
            kind = self.kind
        except KeyError:
            return  # the study_type field reports the unknown type
        errors = kind.clean_study(self)
        problem = self.crowd_problem()
        if problem:
            errors["crowd"] = problem
        if errors:
            raise ValidationError(errors)

    def crowd_problem(self) -> str:
        """Return what is wrong with the crowd settings for this study ("" when nothing):
        a bad setting, or an outcome the study can end with that lacks its code."""
        try:
            platform = self.platform
            platform.check_codes(self.coded_outcomes(), self.n_checks())
        except ValueError as exc:
            return str(exc)
        return ""

    def crowd_warnings(self) -> list[str]:
        """Return what the platform's rules advise against (e.g. too few checks)."""
        try:
            platform = self.platform
        except ValueError:
            return []
        return platform.warnings(self.minutes(), self.n_checks(), self.max_failed_catch)

    def n_checks(self) -> int:
        """Return the attention checks of a session: catch and instructed trials."""
        return (self.catch_trials or 0) + (self.instructed_checks or 0)

    def coded_outcomes(self) -> list[str]:
        """Return the outcomes with a completion code this study can end with."""
        return outcomes_of(self.n_checks(), bool((self.crowd or {}).get("screening")))

    def shown_instructions(self) -> str:
        """Return the instructions, or the study type's default when left blank."""
        return self.instructions or self.kind.default_instructions(self)

    def shown_consent(self) -> str:
        """Return the consent text, or the type's default saying how long the study takes."""
        return self.consent_text or self.kind.default_consent(self.minutes())

    def duration(self) -> Duration:
        """Return how long a session takes: estimated from the study's trials and clips,
        and measured (the median of completed participants' sessions) once there are
        enough of them (:mod:`studyapp.participation.duration`)."""
        if self.pk is None:
            return Duration(fixed_seconds(self.ask_demographics))
        Participant = model("Participant")
        rows = (Participant.objects.filter(study=self, outcome=Participant.Outcome.COMPLETED)
                .exclude(consented_at=None).exclude(completed_at=None)
                .values_list("consented_at", "completed_at"))
        return study_duration(self, [(done - start).total_seconds() for start, done in rows])

    def minutes(self) -> int:
        """Return the whole minutes a session takes, measured once it can be.

        On a row the process keeps (``StudyManager.cached``: the participant pages) the
        minutes are worked out at most every ``MINUTES_KEPT_S`` seconds per version of the
        row; a row read otherwise (the admin, commands) works them out every time."""
        worked_out = self.__dict__.get("_worked_out")
        if worked_out is None:
            return self.duration().minutes
        now = time.monotonic()
        kept = worked_out.get("minutes")
        if kept is not None and kept[0] == self.version and now - kept[1] < MINUTES_KEPT_S:
            return kept[2]
        minutes = self.duration().minutes
        worked_out["minutes"] = (self.version, now, minutes)
        return minutes

    def option(self, name: str):
        """Return the study type's option ``name`` (its default when not set)."""
        return self.kind.option(self, name)

    def time_limit(self) -> timedelta | None:
        """Return how long after consent a participant may finish (None: no limit)."""
        return self.platform.time_limit(self.minutes)

    def idle_limit(self) -> timedelta | None:
        """Return how long a participant may go without answering a trial (None: ever)."""
        return self.platform.idle_limit()

    def is_full(self) -> bool:
        """Whether finished and active participants fill ``max_participants``."""
        if self.max_participants is None:
            return False
        return model("Participant").objects.holding_a_place(self).count() >= self.max_participants

    def participant_url(self, base: str = "") -> str:
        """Return the link participants open, absolute when ``base`` is a site URL."""
        return base.rstrip("/") + self.get_absolute_url()


# --- written out (:mod:`.rows`) ----------------------------------------------------------------

STUDY_ROW = Columns(Study, "s")
_LOCK = Statements(lambda: (
    f"SELECT {STUDY_ROW.sql()} FROM {quote(Study._meta.db_table)} s WHERE s.{quote('id')} = %s"
    + (" FOR UPDATE" if connection.features.has_select_for_update else "")))
_VERSION = Statements(lambda: (
    f"SELECT s.{quote('id')}, s.{quote('version')} FROM {quote(Study._meta.db_table)} s "
    f"WHERE s.{quote('slug')} = %s"))
