"""Background stimulus builds and their progress."""

from django.db import models

from studyapp.survey.models.study import Study


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
