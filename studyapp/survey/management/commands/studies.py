import json
from collections import Counter

from django.core.management.base import BaseCommand, CommandError
from django.db import DatabaseError
from django.urls import reverse

from studyapp.survey import site
from studyapp.survey.models import Participant, Stimulus, Study

OUTCOME_WORDS = {"completed": "completed", "failed_attention": "failed attention (excluded)",
                 "no_consent": "did not consent", "screened_out": "screened out",
                 "timed_out": "timed out"}


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
            ended = ", ".join(f"{n} {OUTCOME_WORDS.get(outcome, outcome)}"
                              for outcome, n in row["outcomes"].items()) or "none ended"
            self.stdout.write(
                f"{row['slug']} ({row['type']}, {row['status']}): {row['participants']} "
                f"participants ({ended}), {row['judgements']} judgements; sources "
                f"{', '.join(row['sources'])}\n"
                f"  {row['participant_url']}"
            )

    def describe(self, study, base_url: str) -> dict:
        judged = Stimulus.objects.judged().filter(study=study)
        ended = Counter(study.participants.exclude(outcome="").values_list("outcome", flat=True))
        outcomes = {o: ended[o] for o in Participant.Outcome.values if ended[o]}
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
            # Outcomes, each person once: "completed" are those who finished and passed the
            # checks, "excluded" those who failed them (finished or not).
            "completed": outcomes.get(Participant.Outcome.COMPLETED, 0),
            "excluded": study.n_excluded,
            "outcomes": outcomes,
            "judgements": study.n_judgements,
        }
