"""Studies, their stimuli, participants, trials and answers.

A judgement is one :class:`TrialItem` of an answered trial that is not a practice
trial, with its answer filled in: ``rank`` (ranking), ``rating`` (1..5) or
``judged_real`` on the item, or ``choice`` on the trial (pairwise). Catch and repeated
trials are judgements too, marked by ``Trial.kind`` and graded in
``Trial.catch_passed``. What a trial asks and how its answer is checked belongs to the
study's type (:mod:`studyapp.survey.study_types`).
"""

import random
import secrets

from django.core.exceptions import ValidationError
from django.core.validators import MaxValueValidator, MinValueValidator
from django.db import connection, models, transaction
from django.db.models import Count, F, OuterRef, Q, Subquery
from django.db.models.functions import Coalesce
from django.urls import reverse
from django.utils import timezone

# Query parameters crowd platforms append to the study link; the first group names a
# person, so the same value cannot take a study twice.
IDENTITY_PARAMS = ("PROLIFIC_PID", "workerId", "participant_label")
EXTERNAL_PARAMS = IDENTITY_PARAMS + ("STUDY_ID", "SESSION_ID", "assignmentId", "hitId")


def new_token() -> str:
    """Return an opaque, unguessable URL token."""
    return secrets.token_urlsafe(16)


def new_completion_code() -> str:
    """Return a short code a participant pastes into the crowd platform."""
    return secrets.token_hex(4).upper()


def study_type_choices():
    """Return the registered study types as field choices."""
    from studyapp.survey.study_types import choices

    return choices()


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
        """Create a study of a registered type, filling in its default texts."""
        from studyapp.survey.study_types import get_study_type

        kind = get_study_type(study_type)
        fields.setdefault("clips_per_trial", kind.default_clips_per_trial)
        study = self.model(study_type=study_type, slug=slug, title=title, **fields)
        study.instructions = study.instructions or kind.default_instructions(study)
        study.consent_text = study.consent_text or kind.default_consent
        study.full_clean()
        study.save()
        return study

    def create_ranking(self, slug: str, title: str, **fields) -> "Study":
        """Create a preference-ranking study (seed 000, Sec. 4.2.5)."""
        return self.create_study("ranking", slug, title, **fields)

    def with_counts(self):
        """Annotate participants started/completed and answered judgements."""
        participants = Participant.objects.filter(study=OuterRef("pk"))
        judgements = TrialItem.objects.filter(
            trial__participant__study=OuterRef("pk"), trial__answered_at__isnull=False
        )
        failed = Trial.objects.filter(kind=Trial.Kind.CATCH, catch_passed=False)
        return self.annotate(
            n_started=_count(participants, "study"),
            n_completed=_count(participants.filter(completed_at__isnull=False), "study"),
            n_judgements=_count(
                judgements.exclude(trial__kind=Trial.Kind.PRACTICE), "trial__participant__study"
            ),
            n_excluded=_count(
                participants.filter(pk__in=failed.values("participant")), "study"
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
    class Type(models.TextChoices):
        """Keys of the built-in study types; the registry in ``study_types`` decides."""

        RANKING = "ranking", "Preference ranking"
        FAKE_OR_REAL = "fake_or_real", "Fake or real"
        RATING_STANDARDS = "rating_standards", "Realism rating with scoring standards"
        RATING_REFERENCE = "rating_reference", "Realism rating with a real reference"
        PAIRWISE = "pairwise", "Pairwise preference"

    class Status(models.TextChoices):
        DRAFT = "draft", "Draft"
        OPEN = "open", "Open"
        CLOSED = "closed", "Closed"

    slug = models.SlugField(unique=True)
    title = models.CharField(max_length=200, help_text="Shown to participants: name no method.")
    study_type = models.CharField(max_length=32, choices=study_type_choices, default=Type.RANKING)
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
    repeat_trials = models.PositiveSmallIntegerField(
        default=0, help_text="Main trials shown again later, to measure consistency."
    )
    allow_ties = models.BooleanField(
        default=False, help_text='Pairwise: also offer "both equally good" and "both equally bad".'
    )
    ask_demographics = models.BooleanField(
        default=False, help_text="Ask age range, gender and comments (all optional) at the end."
    )
    instructions = models.TextField(blank=True)
    consent_text = models.TextField(blank=True)
    completion_url = models.URLField(blank=True, help_text="Where to send participants at the end.")
    max_participants = models.PositiveIntegerField(null=True, blank=True)
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
        from studyapp.survey.study_types import get_study_type

        return get_study_type(self.study_type)

    def clean(self):
        try:
            kind = self.kind
        except KeyError:
            return  # the study_type field reports the unknown type
        if not kind.min_items <= self.clips_per_trial <= (kind.max_items or self.clips_per_trial):
            most = f" and at most {kind.max_items}" if kind.max_items else ""
            raise ValidationError(
                {"clips_per_trial": f"A {kind.label.lower()} trial shows at least "
                 f"{kind.min_items}{most} clips."}
            )

    def shown_instructions(self) -> str:
        """Return the instructions, or the study type's default when left blank."""
        return self.instructions or self.kind.default_instructions(self)

    def shown_consent(self) -> str:
        return self.consent_text or self.kind.default_consent

    def is_full(self) -> bool:
        return (
            self.max_participants is not None
            and self.participants.count() >= self.max_participants
        )

    def participant_url(self, base: str = "") -> str:
        """Return the link participants open, absolute when ``base`` is a site URL."""
        return base.rstrip("/") + self.get_absolute_url()


class StimulusManager(models.Manager):
    def judged(self):
        """Return the stimuli that can be judged: no catch, reference or example clips."""
        return self.filter(is_catch=False, is_reference=False, is_standard_example=False)

    def with_judgements(self):
        """Annotate ``n_judgements``: answered, non-practice trial items of each stimulus."""
        answered = Q(items__trial__answered_at__isnull=False) & ~Q(
            items__trial__kind=Trial.Kind.PRACTICE
        )
        return self.annotate(n_judgements=Count("items", filter=answered))


class Stimulus(models.Model):
    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="stimuli")
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    action = models.CharField(max_length=100)
    source = models.CharField(max_length=100, help_text="'real' or a method key; never shown.")
    video = models.CharField(max_length=300, help_text="Path under MEDIA_ROOT.")
    poster = models.CharField(max_length=300, blank=True)
    duration = models.FloatField(help_text="Seconds.")
    motion_hash = models.CharField(max_length=64, blank=True)
    video_hash = models.CharField(max_length=64, blank=True)
    is_catch = models.BooleanField(
        default=False, help_text="An obviously broken clip for attention checks."
    )
    is_reference = models.BooleanField(
        default=False, help_text="A real clip shown for reference, never rated."
    )
    is_standard_example = models.BooleanField(
        default=False, help_text="The example clip of a scoring standard, never rated."
    )
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
            models.CheckConstraint(
                condition=Q(is_catch=False, is_reference=False)
                | Q(is_catch=False, is_standard_example=False)
                | Q(is_reference=False, is_standard_example=False),
                name="at_most_one_stimulus_role",
            ),
        ]

    def __str__(self):
        return f"{self.study.slug}:{self.action}:{self.source}:{self.pk}"

    def get_absolute_url(self):
        return reverse("survey:clip", args=[self.token, "mp4"])

    def poster_url(self) -> str:
        return reverse("survey:clip", args=[self.token, "png"]) if self.poster else ""


class ParticipantManager(models.Manager):
    def find(self, study: Study, external_ids: dict):
        """Return the participant whose platform id is in ``external_ids``, or None."""
        key = external_key(external_ids)
        return self.filter(study=study, external_key=key).first() if key else None

    def enroll(self, study: Study, external_ids: dict, user_agent: str = "") -> "Participant":
        """Admit a consenting participant, or raise :class:`Unavailable`."""
        with transaction.atomic():
            study = Study.objects.lock(study.pk)
            existing = self.find(study, external_ids)
            if existing is not None:
                if existing.completed_at is not None:
                    raise Unavailable("taken")
                return existing
            if study.status != Study.Status.OPEN:
                raise Unavailable("closed")
            if study.is_full():
                raise Unavailable("full")
            return self.create(
                study=study,
                external_ids=external_ids,
                external_key=external_key(external_ids),
                seed=secrets.randbits(62),
                consented_at=timezone.now(),
                user_agent=user_agent[:300],
            )

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
                    kind=plan.kind,
                    repeat_of=created.get(id(plan.repeat_of)),
                    reference=plan.reference,
                )
                created[id(plan)] = trial
                TrialItem.objects.bulk_create(
                    TrialItem(trial=trial, stimulus=stimulus, position=position)
                    for position, stimulus in enumerate(plan.stimuli)
                )

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

    def with_checks(self):
        """Annotate judgements and the catch / repeat trials answered and failed."""
        answered = Q(trials__answered_at__isnull=False)
        failed = Q(trials__catch_passed=False)

        def trials(kind, also):
            return Count("trials", filter=also & Q(trials__kind=kind), distinct=True)

        return self.annotate(
            n_judgements=Count(
                "trials__items", filter=answered & ~Q(trials__kind=Trial.Kind.PRACTICE)
            ),
            n_catch=trials(Trial.Kind.CATCH, answered),
            failed_catch=trials(Trial.Kind.CATCH, failed),
            n_repeat=trials(Trial.Kind.REPEAT, answered),
            inconsistent_repeats=trials(Trial.Kind.REPEAT, failed),
        )


def external_key(external_ids: dict) -> str:
    """Return ``"PARAM:value"`` for the first identity parameter present, else ``""``."""
    for param in IDENTITY_PARAMS:
        if external_ids.get(param):
            return f"{param}:{external_ids[param]}"
    return ""


class Participant(models.Model):
    study = models.ForeignKey(Study, on_delete=models.CASCADE, related_name="participants")
    token = models.CharField(max_length=32, unique=True, default=new_token, editable=False)
    external_ids = models.JSONField(default=dict, blank=True, help_text="Crowd-platform ids.")
    external_key = models.CharField(
        max_length=200, blank=True, help_text="The platform id that names this person."
    )
    seed = models.BigIntegerField(help_text="Seed of this participant's random order.")
    created_at = models.DateTimeField(auto_now_add=True)
    consented_at = models.DateTimeField(null=True, blank=True)
    completed_at = models.DateTimeField(null=True, blank=True)
    completion_code = models.CharField(max_length=32, blank=True)
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

    def current_trial(self):
        """Return the first unanswered trial, or None."""
        return self.trials.filter(answered_at__isnull=True).order_by("index").first()

    def has_trials(self) -> bool:
        """Return whether the trials were made (from ``by_token``'s count when read so)."""
        n_trials = getattr(self, "n_trials", None)
        return self.trials.exists() if n_trials is None else n_trials > 0

    def excluded(self) -> bool:
        """Return whether the participant failed a catch trial: the analysis's default
        exclusion (``max_failed_catch`` 0). A repeated trial answered differently is a
        reliability figure, not an exclusion, unless the analysis is told so."""
        return self.trials.filter(kind=Trial.Kind.CATCH, catch_passed=False).exists()


class TrialManager(models.Manager):
    def mark_shown(self, trial: "Trial") -> None:
        """Record when the trial was first shown; reloads keep the first time."""
        if trial.shown_at is not None:
            return  # a reload: ``trial`` was just read, so the database has it too
        now = timezone.now()
        if self.filter(pk=trial.pk, shown_at__isnull=True).update(shown_at=now):
            trial.shown_at = now

    def record_answer(
        self, trial: "Trial", answers: dict[int, dict], fields: dict | None = None, items=None
    ) -> bool:
        """Store ``{item id: {field: value}}`` for every item of a trial, once.

        ``fields`` are answers stored on the trial itself (a pairwise ``choice``). A
        practice trial keeps only its plays: its answer is no judgement. A catch or
        repeated trial is graded by the study type into ``catch_passed``. ``items`` are
        the trial's items when the caller has read them already (with their stimuli).
        ``trial.shown_at`` must be as read in this request (a trial never shown counts
        from now). When this answer is the participant's last, ``completed_at`` is set
        on ``trial.participant`` too.

        Return False (and store nothing) when the trial was already answered. The
        conditional UPDATE comes first so two simultaneous submits cannot both win.
        """
        now = timezone.now()
        fields = dict(fields or {})
        if trial.kind == Trial.Kind.PRACTICE:
            answers = {pk: {"plays": values["plays"]} for pk, values in answers.items()}
            fields = {}
        shown_at = trial.shown_at or now
        time_ms = max(0, round((now - shown_at).total_seconds() * 1000))
        with transaction.atomic():
            won = self.filter(pk=trial.pk, answered_at__isnull=True).update(
                answered_at=now, time_ms=time_ms, shown_at=shown_at, **fields
            )
            if not won:
                return False
            trial.answered_at, trial.time_ms, trial.shown_at = now, time_ms, shown_at
            for name, value in fields.items():
                setattr(trial, name, value)
            items = list(items) if items is not None else list(trial.items.select_related("stimulus"))
            names = sorted({name for values in answers.values() for name in values})
            for item in items:
                for name, value in answers[item.pk].items():
                    setattr(item, name, value)
            TrialItem.objects.bulk_update(items, names)
            participant = trial.participant
            if trial.kind in (Trial.Kind.CATCH, Trial.Kind.REPEAT):
                passed = participant.study.kind.grade(trial, items)
                self.filter(pk=trial.pk).update(catch_passed=passed)
            if not participant.trials.filter(answered_at__isnull=True).exists():
                code = new_completion_code()
                if Participant.objects.filter(pk=participant.pk, completed_at__isnull=True).update(
                    completed_at=now, completion_code=code
                ):
                    participant.completed_at, participant.completion_code = now, code
        return True


class Trial(models.Model):
    class Kind(models.TextChoices):
        PRACTICE = "practice", "Practice (not a judgement)"
        MAIN = "main", "Main"
        CATCH = "catch", "Catch (a broken clip)"
        REPEAT = "repeat", "Repeat of an earlier trial"

    class Choice(models.TextChoices):
        LEFT = "left", "Left"
        RIGHT = "right", "Right"
        BOTH_GOOD = "both_good", "Both equally good"
        BOTH_BAD = "both_bad", "Both equally bad"

    participant = models.ForeignKey(Participant, on_delete=models.CASCADE, related_name="trials")
    index = models.PositiveIntegerField(help_text="Order in the participant's session.")
    action = models.CharField(max_length=100)
    kind = models.CharField(max_length=16, choices=Kind.choices, default=Kind.MAIN)
    choice = models.CharField(
        max_length=16, choices=Choice.choices, blank=True, help_text="Pairwise answer."
    )
    catch_passed = models.BooleanField(
        null=True, blank=True, help_text="Catch: broken clip spotted; repeat: answered as before."
    )
    repeat_of = models.ForeignKey(
        "self", on_delete=models.CASCADE, null=True, blank=True, related_name="repeats"
    )
    reference = models.ForeignKey(
        Stimulus, on_delete=models.PROTECT, null=True, blank=True, related_name="+",
        help_text="The reference clip shown beside the judged clips.",
    )
    shown_at = models.DateTimeField(null=True, blank=True)
    answered_at = models.DateTimeField(null=True, blank=True)
    time_ms = models.PositiveIntegerField(null=True, blank=True, help_text="Time to answer.")

    objects = TrialManager()

    class Meta:
        ordering = ["participant", "index"]
        constraints = [
            models.UniqueConstraint(fields=["participant", "index"], name="one_trial_per_index")
        ]

    def __str__(self):
        return f"{self.participant}: trial {self.index}"


class TrialItem(models.Model):
    trial = models.ForeignKey(Trial, on_delete=models.CASCADE, related_name="items")
    stimulus = models.ForeignKey(Stimulus, on_delete=models.PROTECT, related_name="items")
    position = models.PositiveSmallIntegerField(help_text="Place on screen, 0 = first.")
    rank = models.PositiveSmallIntegerField(null=True, blank=True, help_text="1 = best.")
    rating = models.PositiveSmallIntegerField(
        null=True, blank=True, validators=[MinValueValidator(1), MaxValueValidator(5)],
        help_text="1..5, higher = more realistic.",
    )
    judged_real = models.BooleanField(null=True, blank=True)
    plays = models.PositiveIntegerField(default=0)

    class Meta:
        ordering = ["trial", "position"]
        constraints = [
            models.UniqueConstraint(fields=["trial", "position"], name="one_item_per_position"),
            models.UniqueConstraint(fields=["trial", "stimulus"], name="one_item_per_stimulus"),
        ]

    def __str__(self):
        return f"{self.trial}: position {self.position}"


class ResponseManager(models.Manager):
    def get_queryset(self):
        return (
            super()
            .get_queryset()
            .filter(trial__answered_at__isnull=False)
            .exclude(trial__kind=Trial.Kind.PRACTICE)
        )


class Response(TrialItem):
    """An answered trial item: one judgement (a view for the admin)."""

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
                Stimulus.objects.filter(pk=stimulus.pk).update(is_standard_example=True)
                stimulus.is_standard_example = True
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
        limit_choices_to={"is_standard_example": True},
        help_text="The example clip: a stimulus marked standard example, never rated.",
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
        if stimulus is not None and not stimulus.is_standard_example:
            raise ValidationError(
                {"stimulus": "Mark the example clip as a standard example so it is never rated."}
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
