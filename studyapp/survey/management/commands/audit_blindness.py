import json
from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from studyapp.survey.audit import audit_study, http_fetcher, passed
from studyapp.survey.export import get_study


class Command(BaseCommand):
    help = (
        "Fetch every clip of a study from the server as a participant's browser does and "
        "check that nothing observable (byte sizes, headers, MP4 boxes and frame sizes, "
        "duration, picture and poster size) tells real from generated clips, or catch clips "
        "from the others: a cross-validated logistic regression must not beat chance by more "
        "than a small margin. Exits with status 1 when it does."
    )

    def add_arguments(self, parser):
        parser.add_argument("--study", required=True, metavar="SLUG")
        parser.add_argument("--url", required=True,
                            help="The server participants use, e.g. http://127.0.0.1:8000.")
        parser.add_argument("--json", metavar="OUT", dest="json_out",
                            help="Also write the result as JSON.")

    def handle(self, *args, study, url, json_out=None, **options):
        record = get_study(study)
        try:
            result = audit_study(record, http_fetcher(url))
        except (OSError, RuntimeError) as error:
            raise CommandError(f"the clips of {record.slug} could not be fetched from {url}: "
                               f"{error}; is the server running there?") from None
        if json_out:
            Path(json_out).write_text(json.dumps(result, indent=2) + "\n")
        for label, part in result.items():
            shown = "n/a" if part["accuracy"] is None else f"{part['accuracy']:.2f}"
            verdict = "passed" if part["passed"] else "FAILED"
            self.stdout.write(
                f"{label}: accuracy {shown} against chance {part['chance']:.2f} "
                f"(margin {part['margin']:.2f}, {part['n']} clips): {verdict}")
        if not passed(result):
            raise CommandError(
                f"study {record.slug}: clips can be told apart by what the browser receives; "
                f"render every clip with the same settings (one build, one style and size) "
                f"and serve it through this app")
