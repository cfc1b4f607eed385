import json
from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from studyapp.results.audit import LEVELS, audit_study, http_fetcher, passed
from studyapp.results.export import get_study


class Command(BaseCommand):
    help = (
        "Fetch every clip of a study from the server as participants' browsers do and "
        "test whether a script can tell real from generated clips, or catch clips from the "
        "others, by what it is sent: a permutation test of cross-validated classifiers per "
        "family of features, with its p-value and the smallest leak it could have seen. "
        "The deep level (the default) shows every clip twice and also parses the files "
        "(true H.264 frame sizes, the player's joints, hashes of every delivery); basic "
        "reads what a browser receives of one delivery. Exits with status 1 on a leak."
    )

    def add_arguments(self, parser):
        parser.add_argument("--study", required=True, metavar="SLUG")
        parser.add_argument("--url", required=True,
                            help="The server participants use, e.g. http://127.0.0.1:8000.")
        parser.add_argument("--level", choices=LEVELS, default="deep",
                            help="deep (default): every family and two deliveries of every "
                                 "clip; basic: what a browser receives, one delivery.")
        parser.add_argument("--json", metavar="OUT", dest="json_out",
                            help="Also write the result as JSON.")

    def handle(self, *args, study, url, level="deep", json_out=None, **options):
        record = get_study(study)
        try:
            result = audit_study(record, http_fetcher(url), level)
        except (OSError, RuntimeError) as error:
            raise CommandError(f"the clips of {record.slug} could not be fetched from {url}: "
                               f"{error}; is the server running there?") from None
        if json_out:
            Path(json_out).write_text(json.dumps(result, indent=2) + "\n")
        for label, part in result.items():
            self.stdout.write(f"{label}: {part['says']}")
        if not passed(result):
            failed = ", ".join(label for label, part in result.items() if not part["passed"])
            raise CommandError(
                f"study {record.slug}: clips can be told apart by what is sent ({failed}); "
                f"render every clip in one build (build_stimuli: one style, size and framing, "
                f"padded files) and serve it through this app")
