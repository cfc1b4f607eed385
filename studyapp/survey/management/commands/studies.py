import json

from django.core.management.base import BaseCommand, CommandError
from django.db import DatabaseError
from django.urls import reverse

from studyapp.survey.models import Stimulus, Study
from studyapp.survey import site


class Command(BaseCommand):
    help = "List the studies with their type, status, sources, links and progress."

    def add_arguments(self, parser):
        parser.add_argument(
            "--json", action="store_true", dest="as_json", help="One JSON list, for scripts."
        )
        parser.add_argument(
            "--base-url", default=None,
            help="Site the links start with (default: STUDY_BASE_URL, else the address the "
                 "last `demo` served on, else http://127.0.0.1:8000).",
        )

    def handle(self, *args, as_json=False, base_url=None, **options):
        base_url = base_url or site.base_url()
        try:
            rows = [self.describe(study, base_url) for study in Study.objects.with_counts()]
        except DatabaseError as error:
            raise CommandError(f"cannot read the studies ({error}); run `python manage.py "
                               f"migrate` first (make demo does)") from None
        if as_json:
            self.stdout.write(json.dumps(rows, indent=2))
            return
        if not rows:
            self.stdout.write("No studies yet; `python manage.py demo --no-serve` builds some.")
        for row in rows:
            self.stdout.write(
                f"{row['slug']} ({row['type']}, {row['status']}): {row['participants']} "
                f"participants, {row['completed']} completed, {row['excluded']} excluded, "
                f"{row['judgements']} judgements; sources {', '.join(row['sources'])}\n"
                f"  {row['participant_url']}"
            )

    def describe(self, study, base_url: str) -> dict:
        judged = Stimulus.objects.judged().filter(study=study)
        return {
            "slug": study.slug,
            "title": study.title,
            "type": study.study_type,
            "status": study.status,
            "sources": sorted(set(judged.values_list("source", flat=True))),
            "stimuli": judged.count(),
            "participant_url": study.participant_url(base_url),
            "preview_url": base_url.rstrip("/") + reverse("survey:preview", args=[study.slug]),
            "participants": study.n_started,
            "completed": study.n_completed,
            "excluded": study.n_excluded,
            "judgements": study.n_judgements,
        }
