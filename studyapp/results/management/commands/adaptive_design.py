from django.core.management.base import BaseCommand

from studyapp.results.adaptive import recompute
from studyapp.results.export import get_study


class Command(BaseCommand):
    help = ("Recompute an adaptive study's sampling distribution over pairs (or sets) of sources from "
            "its answers so far (run in the background every few answers; see README).")

    def add_arguments(self, parser):
        parser.add_argument("study", help="the study's slug")

    def handle(self, *args, **options):
        study = get_study(options["study"])
        sampling = recompute(study)
        drawn = sampling.get("sets") or sampling["pairs"]
        likely = sorted(zip(sampling["p"], drawn), reverse=True)[:5]
        names = sampling["sources"]
        top = ", ".join(f"{'-'.join(names[i] for i in members)} {p:.2f}" for p, members in likely)
        what = "sets" if sampling.get("sets") else "pairs"
        self.stdout.write(f"{study.slug}: {sampling['comparisons']} decided "
                          f"{'choices' if what == 'sets' else 'comparisons'} of "
                          f"{sampling['answers']} answered main trials; most likely {what}: {top}")
