"""Studies, their stimuli, participants, trials and answers.

A trial shows items: the clips to judge (``TrialItem.role`` ``judged``) and the clips
shown beside them for context (a real ``reference``, the ``example`` clips of a scoring
standard). Every item has its own opaque token, so the same clip shown twice (a repeated
trial) is two URLs, and the server knows which item's bytes a participant fetched.

A judgement is one judged item of an answered trial that is not a practice trial. Its
answer is stored per criterion: ``TrialItem.answers`` (``{"preference": 2}``, a rank) and
``Trial.answers`` (``{"preference": "left"}``, a pairwise choice). What a trial asks, how
its answer is checked, graded, exported and analysed belongs to the study's type
(:mod:`studyapp.survey.study_types`); nothing here branches on it.
"""

import random
import secrets
from datetime import timedelta

from django.core.exceptions import ValidationError
from django.core.validators import MaxValueValidator, MinValueValidator
from django.db import connection, models, transaction
from django.db.models import Count, Exists, F, OuterRef, Q, Subquery
from django.db.models.functions import Coalesce
from django.urls import reverse
from django.utils import timezone

from studyapp.crowd.platform import outcomes_of, platform_of
from studyapp.participation.duration import Duration, fixed_seconds, study_duration
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


class StudyManager(models.Manager):
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
        """Return the study row locked until the end of the current transaction.

        PostgreSQL takes a row lock (FOR UPDATE). SQLite ignores FOR UPDATE, so a no-op
        UPDATE takes its database write lock first: concurrent assigners then queue
        instead of reading the same counts.
        """
        if connection.vendor == "sqlite":
            self.filter(pk=study_id).update(status=F("status"))
        return self.select_for_update().get(pk=study_id)


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
        rows = (Participant.objects.filter(study=self, outcome=Participant.Outcome.COMPLETED)
                .exclude(consented_at=None).exclude(completed_at=None)
                .values_list("consented_at", "completed_at"))
        return study_duration(self, [(done - start).total_seconds() for start, done in rows])

    def minutes(self) -> int:
        """Return the whole minutes a session takes, measured once it can be."""
        return self.duration().minutes

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
        return Participant.objects.holding_a_place(self).count() >= self.max_participants

    def participant_url(self, base: str = "") -> str:
        """Return the link participants open, absolute when ``base`` is a site URL."""
        return base.rstrip("/") + self.get_absolute_url()


class StimulusManager(models.Manager):
    def judged(self):
        """Return the stimuli that are judged in main trials."""
        return self.filter(role=Stimulus.Role.JUDGED)

    def with_judgements(self):
        """Annotate ``n_judgements``: answered, non-practice judged items of each stimulus."""
        answered = (
            Q(items__trial__answered_at__isnull=False)
            & ~Q(items__trial__kind=Trial.Kind.PRACTICE)
            & Q(items__role=TrialItem.Role.JUDGED)
        )
        return self.annotate(n_judgements=Count("items", filter=answered))


class Stimulus(models.Model):
    class Role(models.TextChoices):
        JUDGED = "judged", "Judged"
        CATCH = "catch", "Catch (an obviously broken clip)"
        REFERENCE = "reference", "Reference (a real clip shown or hidden for comparison)"
        EXAMPLE = "example", "Scoring-standard example"
        ANCHOR = "anchor", "Low anchor (a degraded clip rated among the others)"
        PRACTICE = "practice", "Practice only"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="stimuli")
    token = models.CharField(
        max_length=32, unique=True, default=new_token, editable=False,
        help_text="For staff previews only; participants see per-trial tokens.",
    )
    action = models.CharField(max_length=100)
    prompt = models.TextField(blank=True, help_text="The text prompt the motion answers, if any.")
    source = models.CharField(max_length=100, help_text="'real' or a method key; never shown.")
    role = models.CharField(max_length=16, choices=Role.choices, default=Role.JUDGED)
    video = models.CharField(max_length=300, help_text="Storage name of the mp4.")
    poster = models.CharField(max_length=300, blank=True)
    motion = models.CharField(
        max_length=300, blank=True, help_text="Storage name of the in-browser player's data."
    )
    duration = models.FloatField(help_text="Seconds.")
    motion_hash = models.CharField(max_length=64, blank=True)
    video_hash = models.CharField(max_length=64, blank=True)
    checkpoint = models.CharField(
        max_length=64, blank=True,
        help_text="sha256 of the method checkpoint that made the motion; never shown.")
    training_seed = models.IntegerField(
        null=True, blank=True, help_text="That checkpoint's training seed; never shown.")
    created_at = models.DateTimeField(auto_now_add=True)

    objects = StimulusManager()

    class Meta:
        verbose_name_plural = "stimuli"
        ordering = ["study", "action", "source", "id"]
        indexes = [models.Index(fields=["study", "action", "source"])]
        constraints = [
            models.UniqueConstraint(
                fields=["study", "video_hash"],
                condition=~Q(video_hash=""),
                name="one_stimulus_per_video",
            ),
        ]

    def __str__(self):
        return f"{self.study.slug}:{self.action}:{self.source}:{self.pk}"

    @property
    def is_catch(self) -> bool:
        return self.role == self.Role.CATCH

    def preview_url(self, ext: str = "mp4") -> str:
        """Return the staff-only URL of this stimulus' file (the admin, previews)."""
        return reverse("survey:preview_clip", args=[self.token, ext])


class ParticipantManager(models.Manager):
    def find(self, study: Study, key: str):
        """Return the participant whose platform id is ``key``, or None."""
        return self.filter(study=study, external_key=key).first() if key else None

    def holding_a_place(self, study: Study):
        """Return the participants who count against ``max_participants``: finished, or
        consented, still within the study's time limit and not idle."""
        people = self.filter(study=study, consented_at__isnull=False)
        finished = Q(completed_at__isnull=False)
        return people.filter(finished | self._active(study, timezone.now()))

    @staticmethod
    def _active(study: Study, now) -> Q:
        """Return who is taking part now: consented, unfinished, within the time limit and
        the idle limit (the last answer, or consent, recent enough)."""
        active = Q(completed_at__isnull=True, outcome="", consented_at__isnull=False)
        limit, idle = study.time_limit(), study.idle_limit()
        if limit is not None:
            active &= Q(consented_at__gt=now - limit)
        if idle is not None:
            active &= Q(active_at__gt=now - idle) | Q(active_at__isnull=True,
                                                      consented_at__gt=now - idle)
        return active

    def release_places(self, study: Study) -> int:
        """Give the ``timed_out`` outcome to everyone taking part past the time limit or
        the idle limit (their later requests get the timed-out page); return how many.
        Called with the study row locked, before places are counted: no daemon needed."""
        lost = self.filter(study=study, completed_at__isnull=True, outcome="",
                           consented_at__isnull=False).exclude(self._active(study, timezone.now()))
        return lost.update(outcome=Participant.Outcome.TIMED_OUT)

    def enroll(self, study: Study, external_ids: dict, key: str, user_agent: str = "",
               outcome: str = "") -> "Participant":
        """Admit a consenting participant (or record one who declined or was screened out
        with ``outcome``), or raise :class:`Unavailable`."""
        with transaction.atomic():
            study = Study.objects.lock(study.pk)
            existing = self.find(study, key)
            if existing is not None:
                if existing.is_finished():
                    raise Unavailable("taken")
                if existing.timed_out():
                    raise Unavailable("timed_out")
                return existing
            if study.status != Study.Status.OPEN:
                raise Unavailable("closed")
            if self.sharing_ids(study, external_ids, key):
                raise Unavailable("session_taken")
            if not outcome and study.max_participants is not None:
                self.release_places(study)
                if study.is_full():
                    raise Unavailable("full")
            now = timezone.now()
            return self.create(
                study=study,
                external_ids=external_ids,
                external_key=key,
                seed=secrets.randbits(62),
                consented_at=None if outcome else now,
                active_at=None if outcome else now,
                completed_at=now if outcome else None,
                outcome=outcome,
                completion_code=study.platform.code_for(outcome) if outcome else "",
                user_agent=user_agent[:300],
            )

    def sharing_ids(self, study: Study, external_ids: dict, key: str) -> bool:
        """Whether another participant of ``study`` came with one of the ids that must be
        unique (a Prolific ``SESSION_ID`` with ``strict_ids``)."""
        unique = study.platform.unique_ids(external_ids)
        if not unique:
            return False
        same = Q()
        for name, value in unique.items():
            same |= Q(**{f"external_ids__{name}": value})
        return self.filter(study=study).filter(same).exclude(external_key=key).exists()

    def start(self, participant: "Participant") -> None:
        """Create the participant's trials once, balanced against everyone before them."""
        with transaction.atomic():
            study = Study.objects.lock(participant.study_id)
            if participant.trials.exists():
                return
            plans = study.kind.plan_trials(study, random.Random(participant.seed))
            created = {}
            for index, plan in enumerate(plans):
                trial = Trial.objects.create(
                    participant=participant,
                    index=index,
                    action=plan.action,
                    prompt=plan.prompt,
                    kind=plan.kind,
                    repeat_of=created.get(id(plan.repeat_of)),
                    instruction=plan.instruction,
                )
                created[id(plan)] = trial
                TrialItem.objects.bulk_create(plan.items(trial))

    def by_token(self, study: Study, token: str):
        """Return the study's participant with ``token``, or None, with ``n_trials``,
        ``n_practice`` and ``current_id`` (the first unanswered trial, None before the
        start and after the last answer). Every page asks this, so it is one SQL
        statement written out (building it as an annotated queryset costs more CPU than
        running it)."""
        rows = list(self.raw(self._by_token_sql(), [study.pk, token]))
        return rows[0] if rows else None

    @staticmethod
    def _by_token_sql() -> str:
        quote = connection.ops.quote_name
        p, t = quote(Participant._meta.db_table), quote(Trial._meta.db_table)
        trials = f"FROM {t} WHERE {t}.{quote('participant_id')} = {p}.{quote('id')}"
        return (
            f"SELECT {p}.*, "
            f"(SELECT COUNT(*) {trials}) AS n_trials, "
            f"(SELECT COUNT(*) {trials} AND {t}.{quote('kind')} = '{Trial.Kind.PRACTICE}') "
            f"AS n_practice, "
            f"(SELECT {t}.{quote('id')} {trials} AND {t}.{quote('answered_at')} IS NULL "
            f"ORDER BY {t}.{quote('index')} LIMIT 1) AS current_id "
            f"FROM {p} WHERE {p}.{quote('study_id')} = %s AND {p}.{quote('token')} = %s"
        )

    def record_demographics(self, participant: "Participant", answers: dict) -> None:
        """Store the answers to the closing questions once; later posts change nothing."""
        self.filter(pk=participant.pk, demographics__isnull=True).update(demographics=answers)
        participant.refresh_from_db(fields=["demographics"])

    def mark_timed_out(self, participant: "Participant") -> None:
        """Record that the participant ran out of time or sat idle too long (as the
        platform times them out); the place is free again, and no code is given."""
        if self.filter(pk=participant.pk, outcome="", completed_at=None).update(
            outcome=Participant.Outcome.TIMED_OUT
        ):
            participant.outcome = Participant.Outcome.TIMED_OUT

    def finish(self, participant: "Participant", now) -> None:
        """Decide the outcome after the last answer (the study's catch rule) and set the
        completion code: the platform's code of that outcome, or a random code."""
        study = participant.study
        failed = Trial.objects.filter(
            participant=participant, kind__in=Trial.CHECK_KINDS, catch_passed=False
        ).count()
        outcome = (
            Participant.Outcome.FAILED_ATTENTION
            if failed > study.max_failed_catch
            else Participant.Outcome.COMPLETED
        )
        code = study.platform.code_for(outcome)
        if self.filter(pk=participant.pk, completed_at__isnull=True).update(
            completed_at=now, completion_code=code, outcome=outcome
        ):
            participant.completed_at, participant.completion_code = now, code
            participant.outcome = outcome

    def with_checks(self):
        """Annotate judgements, the attention checks (catch and instructed trials, as
        ``n_catch``, ``failed_catch``) and the repeated trials, answered and failed."""
        answered = Q(trials__answered_at__isnull=False)
        failed = Q(trials__catch_passed=False)

        def trials(kind, also):
            kinds = Q(trials__kind__in=kind) if isinstance(kind, tuple) else Q(trials__kind=kind)
            return Count("trials", filter=also & kinds, distinct=True)

        return self.annotate(
            n_judgements=Count(
                "trials__items",
                filter=answered
                & ~Q(trials__kind=Trial.Kind.PRACTICE)
                & Q(trials__items__role=TrialItem.Role.JUDGED),
            ),
            n_catch=trials(Trial.CHECK_KINDS, answered),
            failed_catch=trials(Trial.CHECK_KINDS, failed),
            n_repeat=trials(Trial.Kind.REPEAT, answered),
            inconsistent_repeats=trials(Trial.Kind.REPEAT, failed),
        )


class Participant(models.Model):
    class Outcome(models.TextChoices):
        COMPLETED = "completed", "Completed"
        FAILED_ATTENTION = "failed_attention", "Failed the attention checks"
        NO_CONSENT = "no_consent", "Did not consent"
        SCREENED_OUT = "screened_out", "Screened out"
        TIMED_OUT = "timed_out", "Ran out of time"

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="participants")
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    external_ids = models.JSONField(default=dict, blank=True, help_text="Crowd-platform ids.")
    external_key = models.CharField(
        max_length=200, blank=True, help_text="The platform id that names this person."
    )
    seed = models.BigIntegerField(help_text="Seed of this participant's random order.")
    created_at = models.DateTimeField(auto_now_add=True)
    consented_at = models.DateTimeField(null=True, blank=True)
    active_at = models.DateTimeField(
        null=True, blank=True, help_text="Consent or the last answer: idle since then."
    )
    completed_at = models.DateTimeField(null=True, blank=True)
    outcome = models.CharField(
        max_length=20, choices=Outcome.choices, blank=True, help_text="Blank while taking part."
    )
    completion_code = models.CharField(max_length=64, blank=True)
    user_agent = models.CharField(max_length=300, blank=True)
    demographics = models.JSONField(
        null=True, blank=True, help_text="Age range, gender, comments; empty until asked."
    )

    objects = ParticipantManager()

    class Meta:
        ordering = ["study", "created_at"]
        constraints = [
            models.UniqueConstraint(
                fields=["study", "external_key"],
                condition=~Q(external_key=""),
                name="one_participation_per_person",
            )
        ]

    def __str__(self):
        return f"{self.study.slug}:participant {self.pk}"

    def is_finished(self) -> bool:
        """Whether the participant has an outcome that ends their session with a code."""
        return self.completed_at is not None

    def timed_out(self, now=None) -> bool:
        """Whether the study's time limit passed before the participant finished, or they
        answered no trial for the study's idle limit."""
        if self.outcome == self.Outcome.TIMED_OUT:
            return True
        if self.completed_at is not None or self.consented_at is None or self.outcome:
            return False
        now = now or timezone.now()
        limit, idle = self.study.time_limit(), self.study.idle_limit()
        if limit is not None and now - self.consented_at > limit:
            return True
        return idle is not None and now - (self.active_at or self.consented_at) > idle

    def current_trial(self):
        """Return the first unanswered trial, or None."""
        return self.trials.filter(answered_at__isnull=True).order_by("index").first()

    def has_trials(self) -> bool:
        """Return whether the trials were made (from ``by_token``'s count when read so)."""
        n_trials = getattr(self, "n_trials", None)
        return self.trials.exists() if n_trials is None else n_trials > 0

    def excluded(self) -> bool:
        """Return whether the participant failed the study's attention checks."""
        if self.outcome:
            return self.outcome == self.Outcome.FAILED_ATTENTION
        failed = self.trials.filter(kind__in=Trial.CHECK_KINDS, catch_passed=False).count()
        return failed > self.study.max_failed_catch


class TrialManager(models.Manager):
    def mark_shown(self, trial: "Trial") -> None:
        """Record when the trial page was first served; reloads keep the first time."""
        if trial.shown_at is not None:
            return  # a reload: ``trial`` was just read, so the database has it too
        now = timezone.now()
        if self.filter(pk=trial.pk, shown_at__isnull=True).update(shown_at=now):
            trial.shown_at = now

    def record_answer(self, trial: "Trial", answer, items) -> bool:
        """Store a checked answer (:class:`~studyapp.participation.answers.Answer`) of a trial once.

        A practice trial keeps only its plays and events: its answer is no judgement. A
        catch, instructed or repeated trial is graded by the study type into
        ``catch_passed``. The participant's ``active_at`` moves on (they are not idle).
        ``items`` are the trial's items as read in this request (with their stimuli);
        ``trial.shown_at`` must be as read in this request (a trial never shown counts
        from now). When this answer is the participant's last, the outcome and the
        completion code are set on ``trial.participant`` too.

        Return False (and store nothing) when the trial was already answered. The
        conditional UPDATE comes first so two simultaneous submits cannot both win.
        """
        now = timezone.now()
        practice = trial.kind == Trial.Kind.PRACTICE
        trial_answers = {} if practice else answer.trial
        shown_at = trial.shown_at or now
        time_ms = max(0, round((now - shown_at).total_seconds() * 1000))
        with transaction.atomic():
            won = self.filter(pk=trial.pk, answered_at__isnull=True).update(
                answered_at=now, time_ms=time_ms, shown_at=shown_at, answers=trial_answers,
                events=answer.events,
            )
            if not won:
                return False
            trial.answered_at, trial.time_ms, trial.shown_at = now, time_ms, shown_at
            trial.answers, trial.events = trial_answers, answer.events
            for item in items:
                item.plays = answer.plays.get(item.pk, item.plays)
                item.answers = {} if practice else answer.items.get(item.pk, {})
            TrialItem.objects.bulk_update(items, ["plays", "answers"])
            participant = trial.participant
            if trial.kind in Trial.GRADED_KINDS:
                passed = participant.study.kind.grade(trial, items)
                self.filter(pk=trial.pk).update(catch_passed=passed)
                trial.catch_passed = passed
            # One statement: the participant is active now, unless that was their last
            # answer (no unanswered trial left), when they finish.
            unanswered = Trial.objects.filter(participant=OuterRef("pk"), answered_at__isnull=True)
            if Participant.objects.filter(pk=participant.pk).filter(Exists(unanswered)).update(
                    active_at=now):
                participant.active_at = now
            else:
                Participant.objects.finish(participant, now)
        return True


class Trial(models.Model):
    class Kind(models.TextChoices):
        PRACTICE = "practice", "Practice (not a judgement)"
        MAIN = "main", "Main"
        CATCH = "catch", "Catch (a broken clip)"
        INSTRUCTED = "instructed", "Instructed-response check (the text says what to answer)"
        REPEAT = "repeat", "Repeat of an earlier trial"

    # Attention checks (counted against ``max_failed_catch``), and every graded kind.
    CHECK_KINDS = (Kind.CATCH, Kind.INSTRUCTED)
    GRADED_KINDS = (Kind.CATCH, Kind.INSTRUCTED, Kind.REPEAT)

    participant = models.ForeignKey(Participant, on_delete=models.CASCADE, related_name="trials")
    index = models.PositiveIntegerField(help_text="Order in the participant's session.")
    action = models.CharField(max_length=100)
    prompt = models.TextField(blank=True, help_text="The text prompt shown, if any.")
    kind = models.CharField(max_length=16, choices=Kind.choices, default=Kind.MAIN)
    answers = models.JSONField(
        default=dict, blank=True, help_text="Answers on the trial itself, per criterion."
    )
    catch_passed = models.BooleanField(
        null=True, blank=True, help_text="Catch: broken clip spotted; instructed: the answer "
        "asked for given; repeat: answered as before."
    )
    instruction = models.JSONField(
        default=dict, blank=True, help_text="Instructed check: the answer asked for, as the "
        "study type reads it (e.g. {\"position\": 1})."
    )
    repeat_of = models.ForeignKey(
        "self", on_delete=models.CASCADE, null=True, blank=True, related_name="repeats"
    )
    shown_at = models.DateTimeField(null=True, blank=True, help_text="When the page was served.")
    answered_at = models.DateTimeField(null=True, blank=True)
    time_ms = models.PositiveIntegerField(null=True, blank=True, help_text="Time to answer.")
    events = models.JSONField(
        default=list, blank=True,
        help_text="What the page reported: [ms since shown, event, item position] each.",
    )

    objects = TrialManager()

    class Meta:
        ordering = ["participant", "index"]
        constraints = [
            models.UniqueConstraint(fields=["participant", "index"], name="one_trial_per_index")
        ]

    def __str__(self):
        return f"{self.participant}: trial {self.index}"


class TrialItemManager(models.Manager):
    def judged(self):
        return self.filter(role=TrialItem.Role.JUDGED)

    def record_fetch(self, item_id: int, ext: str, start: int, end: int, size: int) -> None:
        """Record that bytes ``start..end`` (inclusive) of an item's ``ext`` file (its mp4,
        or the in-browser player's payload) were sent whole; the first time the ranges
        of one of its files cover that file, ``fetched_at`` is set."""
        with transaction.atomic():
            if connection.vendor == "sqlite":  # take the write lock first (see StudyManager.lock)
                self.filter(pk=item_id).update(plays=F("plays"))
            item = self.select_for_update().only("fetched", "fetched_at").get(pk=item_id)
            if item.fetched_at is not None:
                return
            fetched = item.fetched if isinstance(item.fetched, dict) else {}
            ranges = merge_ranges([*fetched.get(ext, []), [start, end]])
            fields = {"fetched": {**fetched, ext: ranges}}
            if ranges == [[0, size - 1]]:
                fields["fetched_at"] = timezone.now()
            self.filter(pk=item_id).update(**fields)


def merge_ranges(ranges) -> list[list[int]]:
    """Return inclusive byte ranges merged where they touch or overlap, sorted."""
    out: list[list[int]] = []
    for start, end in sorted([int(a), int(b)] for a, b in ranges):
        if out and start <= out[-1][1] + 1:
            out[-1][1] = max(out[-1][1], end)
        else:
            out.append([start, end])
    return out


class TrialItem(models.Model):
    class Role(models.TextChoices):
        JUDGED = "judged", "Judged"
        REFERENCE = "reference", "Reference shown beside the judged clips"
        EXAMPLE = "example", "Scoring-standard example"

    trial = models.ForeignKey(Trial, on_delete=models.CASCADE, related_name="items")
    stimulus = models.ForeignKey(Stimulus, on_delete=models.PROTECT, related_name="items")
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    role = models.CharField(max_length=16, choices=Role.choices, default=Role.JUDGED)
    position = models.PositiveSmallIntegerField(
        help_text="Place on screen, 0 = first; shown-only clips come after the judged ones."
    )
    required = models.BooleanField(
        default=True, help_text="Must be fetched whole before the trial's answer is taken."
    )
    answers = models.JSONField(default=dict, blank=True, help_text="Answers per criterion.")
    plays = models.PositiveIntegerField(default=0, help_text="Complete plays the page reported.")
    fetched = models.JSONField(
        default=dict, blank=True, help_text="Byte ranges sent whole, per file (mp4, motion)."
    )
    fetched_at = models.DateTimeField(
        null=True, blank=True, help_text="When the whole clip had been sent."
    )

    objects = TrialItemManager()

    class Meta:
        ordering = ["trial", "position"]
        constraints = [
            models.UniqueConstraint(fields=["trial", "position"], name="one_item_per_position"),
            models.UniqueConstraint(
                fields=["trial", "stimulus"], condition=Q(role="judged"),
                name="one_judged_item_per_stimulus",
            ),
        ]

    def __str__(self):
        return f"{self.trial}: position {self.position}"

    def clip_url(self, ext: str = "mp4") -> str:
        """Return the URL of this item's ``mp4``, ``png`` (poster) or ``motion`` (payload)."""
        return reverse("survey:clip", args=[self.token, ext])



class ResponseManager(models.Manager):
    def get_queryset(self):
        return (
            super()
            .get_queryset()
            .filter(trial__answered_at__isnull=False, role=TrialItem.Role.JUDGED)
            .exclude(trial__kind=Trial.Kind.PRACTICE)
        )


class Response(TrialItem):
    """An answered judged trial item: one judgement (a view for the admin)."""

    objects = ResponseManager()

    class Meta:
        proxy = True
        ordering = ["-trial__answered_at", "position"]


class ScoringStandardManager(models.Manager):
    def for_action(self, study: Study, action: str) -> list["ScoringStandard"]:
        """Return the standards of one action, score 1 first, with their clips."""
        return list(
            self.filter(study=study, action=action).select_related("stimulus").order_by("score")
        )

    def set_standards(self, study: Study, action: str, examples: dict, descriptions: dict):
        """Replace the standards of ``action``: ``{score: stimulus}`` and ``{score: text}``."""
        with transaction.atomic():
            self.filter(study=study, action=action).delete()
            standards = []
            for score, stimulus in sorted(examples.items()):
                if stimulus.role != Stimulus.Role.EXAMPLE:
                    Stimulus.objects.filter(pk=stimulus.pk).update(role=Stimulus.Role.EXAMPLE)
                    stimulus.role = Stimulus.Role.EXAMPLE
                standard = self.model(
                    study=study,
                    action=action,
                    score=score,
                    description=descriptions[score],
                    stimulus=stimulus,
                )
                standard.full_clean()
                standard.save()
                standards.append(standard)
        return standards


class ScoringStandard(models.Model):
    """One step of a rating scale for one action: a description and an example clip."""

    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="standards")
    action = models.CharField(max_length=100)
    score = models.PositiveSmallIntegerField(
        validators=[MinValueValidator(1), MaxValueValidator(5)]
    )
    description = models.TextField()
    stimulus = models.ForeignKey(
        Stimulus,
        on_delete=models.RESTRICT,  # deletable only with its standard (e.g. with the study)
        related_name="standards",
        limit_choices_to={"role": "example"},
        help_text="The example clip: a stimulus whose role is example, never rated.",
    )

    objects = ScoringStandardManager()

    class Meta:
        ordering = ["study", "action", "score"]
        constraints = [
            models.UniqueConstraint(
                fields=["study", "action", "score"], name="one_standard_per_score"
            ),
            models.CheckConstraint(
                condition=Q(score__gte=1, score__lte=5), name="standard_score_1_to_5"
            ),
        ]

    def __str__(self):
        return f"{self.study.slug}:{self.action}:{self.score}"

    def clean(self):
        stimulus = self.stimulus if self.stimulus_id else None
        if stimulus is not None and self.study_id and stimulus.study_id != self.study_id:
            raise ValidationError({"stimulus": "The example clip must belong to this study."})
        if stimulus is not None and stimulus.role != Stimulus.Role.EXAMPLE:
            raise ValidationError(
                {"stimulus": "Give the example clip the role 'example' so it is never rated."}
            )


class BuildJob(models.Model):
    """A stimulus build (``build_stimuli CONFIG``) run in the background, with its progress."""

    class Status(models.TextChoices):
        QUEUED = "queued", "Queued"
        RUNNING = "running", "Running"
        DONE = "done", "Done"
        FAILED = "failed", "Failed"

    config_path = models.CharField(max_length=500, help_text="Path of the study's YAML config.")
    overrides = models.JSONField(default=list, blank=True, help_text='e.g. ["dataset=demo"]')
    status = models.CharField(max_length=16, choices=Status.choices, default=Status.QUEUED)
    done = models.PositiveIntegerField(default=0)
    total = models.PositiveIntegerField(default=0)
    message = models.CharField(max_length=300, blank=True)
    error = models.TextField(blank=True)
    study = models.ForeignKey(Study, null=True, blank=True, on_delete=models.SET_NULL)
    created_at = models.DateTimeField(auto_now_add=True)
    started_at = models.DateTimeField(null=True, blank=True)
    finished_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-created_at"]

    def __str__(self):
        return f"build {self.pk}: {self.config_path} ({self.status})"


class FailedLoginManager(models.Manager):
    def record(self, address: str, now=None, keep=timedelta(days=1)) -> None:
        """Count one failed admin login from ``address``; forget those older than ``keep``."""
        now = now or timezone.now()
        self.create(address=address[:64], failed_at=now)
        self.filter(failed_at__lt=now - keep).delete()

    def since(self, address: str, start) -> int:
        """Return the failed logins from ``address`` since ``start``."""
        return self.filter(address=address[:64], failed_at__gte=start).count()


class FailedLogin(models.Model):
    """One failed admin login, by address: the login throttle counts these in the
    database, so it holds across workers without Redis and while the cache is down."""

    address = models.CharField(max_length=64)
    failed_at = models.DateTimeField()

    objects = FailedLoginManager()

    class Meta:
        indexes = [models.Index(fields=["address", "failed_at"])]

    def __str__(self):
        return f"{self.address} at {self.failed_at:%Y-%m-%d %H:%M:%S}"
