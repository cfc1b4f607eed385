"""A study's stimuli (its registered clips, by role) and scoring standards."""

from django.core.exceptions import ValidationError
from django.core.validators import MaxValueValidator, MinValueValidator
from django.db import models, transaction
from django.db.models import Count, Q
from django.urls import reverse

from studyapp.survey.models.study import Study, model, new_token


class StimulusManager(models.Manager):
    def judged(self):
        """Return the stimuli that are judged in main trials."""
        return self.filter(role=Stimulus.Role.JUDGED)

    def with_judgements(self):
        """Annotate ``n_judgements``: answered, non-practice judged items of each stimulus."""
        answered = (
            Q(items__trial__answered_at__isnull=False)
            & ~Q(items__trial__kind=model("Trial").Kind.PRACTICE)
            & Q(items__role=model("TrialItem").Role.JUDGED)
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
