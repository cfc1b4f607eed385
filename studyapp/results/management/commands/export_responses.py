from django.core.management.base import BaseCommand, CommandError

from analysis.tables import AnalysisError, write_responses
from studyapp.results.export import get_study, participants_frame, responses_frame


class Command(BaseCommand):
    help = (
        "Write a study's answers, one row per judgement, to a CSV (or .parquet) file; "
        "with --participants, also one row per participant (catch results, demographics)."
    )

    def add_arguments(self, parser):
        parser.add_argument("--study", required=True, metavar="SLUG")
        parser.add_argument("--out", required=True, metavar="FILE", help=".csv or .parquet")
        parser.add_argument(
            "--participants", metavar="FILE", help="Also write the participant table here."
        )

    def handle(self, *args, study, out, participants=None, **options):
        study = get_study(study)
        table = responses_frame(study)
        try:
            path = write_responses(table, out)
            if participants:
                people = write_responses(participants_frame(study), participants)
        except (AnalysisError, OSError) as error:
            raise CommandError(f"Cannot write {out}: {error}") from None
        if table.empty:
            self.stdout.write(f"Study {study.slug} has no answers yet; wrote the header to {path}.")
        else:
            self.stdout.write(
                f"Wrote {len(table)} judgements from {table['participant'].nunique()} "
                f"participants of {study.slug} to {path}."
            )
        if participants:
            self.stdout.write(f"Wrote the participant table to {people}.")
