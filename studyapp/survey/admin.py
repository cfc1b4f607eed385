"""The researcher's view: studies with their progress, stimuli, participants, answers.

Studies are created, edited, opened and closed here, and previewed as a participant
(a staff-only link whose answers are not stored). Answers are read-only, so a click in
the admin cannot change collected data.
"""

from django.contrib import admin, messages
from django.db import models
from django.db.models import Count, Q
from django.forms import Textarea
from django.urls import reverse
from django.utils.html import format_html, format_html_join

from studyapp.survey.models import (
    BuildJob,
    Participant,
    Response,
    ScoringStandard,
    Stimulus,
    Study,
    Trial,
    TrialItem,
)


class ReadOnlyAdmin(admin.ModelAdmin):
    """Trials and answers as they were stored: nothing added, changed or deleted here (a
    participant is deleted whole, with their trials; the balance counts rely on it)."""

    def has_add_permission(self, request, obj=None):
        return False

    def has_change_permission(self, request, obj=None):
        return False

    def has_delete_permission(self, request, obj=None):
        return False


class ScoringStandardInline(admin.TabularInline):
    model = ScoringStandard
    fields = ["action", "score", "description", "stimulus"]
    extra = 0
    formfield_overrides = {models.TextField: {"widget": Textarea(attrs={"rows": 2, "cols": 60})}}

    def formfield_for_foreignkey(self, db_field, request, **kwargs):
        if db_field.name == "stimulus":
            study_id = request.resolver_match.kwargs.get("object_id")
            kwargs["queryset"] = Stimulus.objects.filter(
                study_id=study_id, role=Stimulus.Role.EXAMPLE
            )
        return super().formfield_for_foreignkey(db_field, request, **kwargs)


@admin.register(Study)
class StudyAdmin(admin.ModelAdmin):
    list_display = [
        "slug",
        "dashboard_link",
        "title",
        "study_type",
        "status",
        "started",
        "completed",
        "judgements",
        "excluded",
        "participant_link",
        "preview_link",
        "results_link",
        "plan_link",
    ]
    list_filter = ["study_type", "status"]
    search_fields = ["slug", "title"]
    readonly_fields = ["dashboard_link", "participant_link", "preview_link", "results_link",
                       "plan_link", "duration", "progress", "created_at", "stopped"]
    actions = ["open_studies", "close_studies"]
    inlines = [ScoringStandardInline]
    fieldsets = [
        ("Progress", {"fields": ["dashboard_link", "participant_link", "preview_link",
                                 "results_link", "plan_link",
                                 "duration", "progress", "created_at"]}),
        (None, {"fields": ["slug", "title", "study_type", "status", "dataset", "data_note"]}),
        (
            "Trials",
            {
                "fields": [
                    "clips_per_trial",
                    "trials_per_participant",
                    "practice",
                    "catch_trials",
                    "instructed_checks",
                    "max_failed_catch",
                    "repeat_trials",
                    "design",
                    "adaptive",
                    "arena",
                    "stop_when",
                    "stopped",
                    "ask_demographics",
                    "options",
                    "criteria",
                ]
            },
        ),
        ("Texts", {"fields": ["instructions", "consent_text"], "classes": ["collapse"]}),
        ("Crowd platform", {"fields": ["crowd", "completion_url", "max_participants"]}),
    ]

    def get_queryset(self, request):
        return Study.objects.with_counts()

    def get_inlines(self, request, obj):
        """Scoring standards only for a study whose type shows scoring-standard examples."""
        if obj is not None and Stimulus.Role.EXAMPLE not in obj.kind.stimulus_roles({}):
            return []
        return super().get_inlines(request, obj)

    def save_model(self, request, obj, form, change):
        """Save the study, then say what its crowd platform's rules advise against (the
        refusals, e.g. a missing completion code, are the form's errors)."""
        super().save_model(request, obj, form, change)
        for warning in obj.crowd_warnings():
            self.message_user(request, warning, messages.WARNING)

    @admin.display(ordering="n_started")
    def started(self, obj):
        return obj.n_started

    @admin.display(ordering="n_completed")
    def completed(self, obj):
        return obj.n_completed

    @admin.display(ordering="n_judgements")
    def judgements(self, obj):
        return obj.n_judgements

    @admin.display(ordering="n_excluded", description="Excluded")
    def excluded(self, obj):
        return obj.n_excluded

    def get_urls(self):
        from django.urls import path

        from studyapp.results import analysis_page as results
        from studyapp.results import dashboard, plan_page

        own = [
            path("<int:pk>/dashboard/", self.admin_site.admin_view(
                lambda request, pk: dashboard.dashboard_view(self.admin_site, request, pk)),
                name="survey_study_dashboard"),
            path("<int:pk>/dashboard/data.json",
                 self.admin_site.admin_view(dashboard.dashboard_data_view),
                 name="survey_study_dashboard_data"),
            path("<int:pk>/plan/", self.admin_site.admin_view(
                lambda request, pk: plan_page.plan_view(self.admin_site, request, pk)),
                name="survey_study_plan"),
            path("<int:pk>/plan/power.png", self.admin_site.admin_view(plan_page.plan_figure_view),
                 name="survey_study_plan_figure"),
            path("<int:pk>/results/", self.admin_site.admin_view(
                lambda request, pk: results.results_view(self.admin_site, request, pk)),
                name="survey_study_results"),
            path("<int:pk>/results/report/", self.admin_site.admin_view(results.report_view),
                 name="survey_study_report"),
            path("<int:pk>/results/report/<slug:criterion>/report.html",
                 self.admin_site.admin_view(results.report_view),
                 name="survey_study_criterion_report"),
        ]
        return own + super().get_urls()

    @admin.display(description="Dashboard")
    def dashboard_link(self, obj):
        if not obj.pk:
            return "-"
        url = reverse("admin:survey_study_dashboard", args=[obj.pk])
        return format_html('<a href="{}"><strong>Live dashboard</strong></a>', url)

    @admin.display(description="Results")
    def results_link(self, obj):
        if not obj.pk:
            return "-"
        return format_html('<a href="{}">Results</a>', reverse("admin:survey_study_results", args=[obj.pk]))

    @admin.display(description="Plan")
    def plan_link(self, obj):
        if not obj.pk:
            return "-"
        return format_html('<a href="{}">Plan</a>', reverse("admin:survey_study_plan", args=[obj.pk]))

    @admin.display(description="Preview")
    def preview_link(self, obj):
        if not obj.pk:
            return "-"
        url = reverse("survey:preview", args=[obj.slug])
        return format_html('<a href="{}" target="_blank" rel="noopener">Preview</a>', url)

    @admin.display(description="Session length")
    def duration(self, obj):
        """The estimate from the study's trials and clips beside the measured median; the
        one the consent, the time limit and the Prolific draft use is named."""
        if not obj.pk:
            return "-"
        found = obj.duration()
        used = "measured" if found.measured is not None else "estimated"
        return f"{found.minutes} minutes ({used}): {found.describe()}."

    @admin.display(description="Live progress")
    def progress(self, obj):
        if not obj.pk:
            return "-"
        counts = Study.objects.with_counts().get(pk=obj.pk)
        # Reference and example clips are never judged: only judged and catch clips count.
        stimuli = (
            Stimulus.objects.with_judgements()
            .filter(study=obj)
            .exclude(role__in=[Stimulus.Role.REFERENCE, Stimulus.Role.EXAMPLE])
            .order_by("action", "source", "pk")
        )
        rows = format_html_join(
            "",
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            ((s.pk, s.action, s.source, s.get_role_display(), s.n_judgements) for s in stimuli),
        )
        return format_html(
            "<p>{} started, {} completed, {} excluded (failed the attention checks), "
            "{} judgements.</p><table><thead><tr><th>Clip</th><th>Action</th><th>Source</th>"
            "<th>Role</th><th>Judgements</th></tr></thead><tbody>{}</tbody></table>",
            counts.n_started,
            counts.n_completed,
            counts.n_excluded,
            counts.n_judgements,
            rows,
        )

    def _set_status(self, request, queryset, status):
        n = Study.objects.filter(pk__in=[study.pk for study in queryset]).update(status=status)
        self.message_user(request, f"{n} {'study' if n == 1 else 'studies'} now {status}.")

    @admin.action(description="Open the selected studies to participants")
    def open_studies(self, request, queryset):
        self._set_status(request, queryset, Study.Status.OPEN)

    @admin.action(description="Close the selected studies")
    def close_studies(self, request, queryset):
        self._set_status(request, queryset, Study.Status.CLOSED)

    @admin.display(description="Participant link")
    def participant_link(self, obj):
        if not obj.pk:
            return "-"
        url = obj.get_absolute_url()
        return format_html('<a href="{}" target="_blank" rel="noopener">{}</a>', url, url)


@admin.register(Stimulus)
class StimulusAdmin(admin.ModelAdmin):
    list_display = [
        "preview",
        "study",
        "action",
        "source",
        "role",
        "duration",
        "n_items",
        "judgements",
        "token",
    ]
    list_filter = ["study", "action", "source", "role"]
    search_fields = ["token", "video_hash", "motion_hash"]
    readonly_fields = ["preview", "token", "video", "poster", "video_hash", "motion_hash"]

    def get_queryset(self, request):
        return Stimulus.objects.with_judgements().annotate(n_items=Count("items", distinct=True))

    @admin.display(description="Trials", ordering="n_items")
    def n_items(self, obj):
        return obj.n_items

    @admin.display(description="Judgements", ordering="n_judgements")
    def judgements(self, obj):
        return obj.n_judgements

    @admin.display(description="Clip")
    def preview(self, obj):
        return format_html(
            '<video src="{}" poster="{}" width="96" muted loop playsinline preload="none" '
            'onmouseover="this.play()" onmouseout="this.pause()"></video>',
            obj.preview_url("mp4"),
            obj.preview_url("png") if obj.poster else "",
        )


class TrialInline(admin.TabularInline):
    model = Trial
    fields = [
        "index", "kind", "action", "answers", "instruction", "catch_passed", "shown_at",
        "answered_at", "time_ms",
    ]
    readonly_fields = fields
    extra = 0
    can_delete = False
    show_change_link = True

    def has_add_permission(self, request, obj=None):
        return False


@admin.register(Participant)
class ParticipantAdmin(admin.ModelAdmin):
    list_display = [
        "pk",
        "study",
        "external_key",
        "consented_at",
        "answered",
        "failed_catch",
        "outcome",
        "completed_at",
        "completion_code",
    ]
    list_filter = ["study", "outcome", ("completed_at", admin.EmptyFieldListFilter)]
    search_fields = ["external_key", "completion_code", "token"]
    readonly_fields = [
        "study",
        "token",
        "external_ids",
        "external_key",
        "seed",
        "created_at",
        "consented_at",
        "active_at",
        "completed_at",
        "outcome",
        "completion_code",
        "user_agent",
        "demographics",
    ]
    inlines = [TrialInline]

    def get_queryset(self, request):
        return (
            super()
            .get_queryset(request)
            .annotate(
                n_trials=Count("trials", distinct=True),
                n_answered=Count(
                    "trials", filter=Q(trials__answered_at__isnull=False), distinct=True
                ),
                failed_catch=Count(
                    "trials",
                    filter=Q(trials__kind__in=Trial.CHECK_KINDS, trials__catch_passed=False),
                    distinct=True,
                ),
            )
        )

    @admin.display(description="Failed attention checks", ordering="failed_catch")
    def failed_catch(self, obj):
        return obj.failed_catch

    @admin.display(description="Answered")
    def answered(self, obj):
        return f"{obj.n_answered} / {obj.n_trials}"

    def has_add_permission(self, request):
        return False

    def get_deleted_objects(self, objs, request):
        """A participant is deleted whole, with their trials and answers, which cannot be
        deleted on their own (``ReadOnlyAdmin``): deleting the participant is allowed."""
        deleted, counts, perms_needed, protected = super().get_deleted_objects(objs, request)
        return deleted, counts, perms_needed - {str(Trial._meta.verbose_name)}, protected


class TrialItemInline(admin.TabularInline):
    model = TrialItem
    fields = ["position", "role", "stimulus", "source", "answers", "plays", "fetched_at"]
    readonly_fields = fields
    extra = 0
    can_delete = False

    @admin.display(description="Source")
    def source(self, obj):
        return obj.stimulus.source

    def has_add_permission(self, request, obj=None):
        return False


@admin.register(Trial)
class TrialAdmin(ReadOnlyAdmin):
    list_display = [
        "__str__",
        "kind",
        "action",
        "answers",
        "catch_passed",
        "shown_at",
        "answered_at",
        "time_ms",
    ]
    list_filter = [
        "participant__study",
        "kind",
        "catch_passed",
        "action",
        ("answered_at", admin.EmptyFieldListFilter),
    ]
    inlines = [TrialItemInline]


@admin.register(Response)
class ResponseAdmin(ReadOnlyAdmin):
    list_display = [
        "participant",
        "study",
        "action",
        "source",
        "kind",
        "position",
        "answers",
        "choice",
        "plays",
        "time_ms",
    ]
    list_filter = [
        "trial__participant__study",
        "trial__kind",
        "stimulus__action",
        "stimulus__source",
    ]
    list_select_related = ["trial__participant__study", "stimulus"]

    @admin.display(ordering="trial__participant")
    def participant(self, obj):
        return obj.trial.participant_id

    @admin.display(ordering="trial__participant__study")
    def study(self, obj):
        return obj.trial.participant.study

    @admin.display(ordering="stimulus__action")
    def action(self, obj):
        return obj.stimulus.action

    @admin.display(ordering="stimulus__source")
    def source(self, obj):
        return obj.stimulus.source

    @admin.display(ordering="trial__kind")
    def kind(self, obj):
        return obj.trial.kind

    @admin.display(description="Answer on the trial")
    def choice(self, obj):
        return obj.trial.answers

    @admin.display(description="Time (ms)", ordering="trial__time_ms")
    def time_ms(self, obj):
        return obj.trial.time_ms


@admin.register(BuildJob)
class BuildJobAdmin(admin.ModelAdmin):
    """Start stimulus builds from a study config and watch their progress (reload the page)."""

    list_display = ["config_path", "status", "progress", "message", "study", "started_at",
                    "finished_at"]
    list_filter = ["status"]
    fields = ["config_path", "overrides", "status", "done", "total", "message", "error",
              "study", "started_at", "finished_at"]
    readonly_fields = ["status", "done", "total", "message", "error", "study", "started_at",
                       "finished_at"]
    actions = ["run_again"]

    @admin.display(description="progress")
    def progress(self, job):
        if not job.total:
            return "—"
        return f"{job.done}/{job.total} ({100 * job.done // job.total} %)"

    def save_model(self, request, job, form, change):
        """Save the job and, when it is new, start it in the background."""
        super().save_model(request, job, form, change)
        if not change:
            self._start(request, job)

    @admin.action(description="Run the selected builds again (safe after a crash)")
    def run_again(self, request, queryset):
        for job in queryset.exclude(status=BuildJob.Status.RUNNING):
            self._start(request, job)

    def _start(self, request, job):
        from studyapp.survey.tasks import run_job

        BuildJob.objects.filter(pk=job.pk).update(status=BuildJob.Status.QUEUED, message="queued")
        run_job("build_stimuli", job=job.pk)
        self.message_user(request, f"Build {job.pk} started; reload this page to follow it.")
