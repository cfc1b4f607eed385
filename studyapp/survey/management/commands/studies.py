import json

from django.core.management.base import BaseCommand
from django.urls import reverse

from studyapp.survey.models import Stimulus, Study


class Command(BaseCommand):
    help = "List the studies with their type, status, sources, links and progress."

    def add_arguments(self, parser):
        parser.add_argument(
            "--json", action="store_true", dest="as_json", help="One JSON list, for scripts."
        )
        parser.add_argument(
            "--base-url", default="http://127.0.0.1:8000", help="Site the links start with."
        )

    def handle(self, *args, as_json=False, base_url="", **options):
        rows = [self.describe(study, base_url) for study in Study.objects.with_counts()]
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
