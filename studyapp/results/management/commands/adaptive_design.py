from django.core.management.base import BaseCommand

from studyapp.results.adaptive import recompute
from studyapp.results.export import get_study


class Command(BaseCommand):
    help = ("Recompute an adaptive study's sampling distribution over pairs of sources from "
            "its answers so far (run in the background every few answers; see README).")

    def add_arguments(self, parser):
        parser.add_argument("study", help="the study's slug")

    def handle(self, *args, **options):
        study = get_study(options["study"])
        sampling = recompute(study)
        pairs = sorted(zip(sampling["p"], sampling["pairs"]), reverse=True)[:5]
        names = sampling["sources"]
        top = ", ".join(f"{names[a]}-{names[b]} {p:.2f}" for p, (a, b) in pairs)
        self.stdout.write(f"{study.slug}: {sampling['comparisons']} decided comparisons of "
                          f"{sampling['answers']} answered main trials; most likely pairs: {top}")
