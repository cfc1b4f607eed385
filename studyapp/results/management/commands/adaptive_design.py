from django.core.management.base import BaseCommand

from studyapp.results.adaptive import recompute
from studyapp.results.export import get_study


class Command(BaseCommand):
    help = ("Recompute an adaptive study's sampling distribution over pairs (or sets) of sources "
            "from its answers so far, and check its stopping rule (run in the background every "
            "few answers; see README).")

    def add_arguments(self, parser):
        parser.add_argument("study", help="the study's slug")

    def handle(self, *args, **options):
        study = get_study(options["study"])
        sampling = recompute(study)
        names = sampling["sources"]
        drawn = sampling.get("sets") or sampling.get("pairs")
        what = "choices" if sampling.get("sets") else "comparisons"
        line = (f"{study.slug}: {sampling['comparisons']} decided {what} of "
                f"{sampling['answers']} answered main trials")
        if drawn:
            likely = sorted(zip(sampling["p"], drawn), reverse=True)[:5]
            top = ", ".join(f"{'-'.join(names[i] for i in members)} {p:.2f}" for p, members in likely)
            line += f"; most likely {'sets' if sampling.get('sets') else 'pairs'}: {top}"
        self.stdout.write(line)
        state = sampling.get("stop")
        if state:
            self.stdout.write(f"stopping rule {study.stop_when}: widest interval {state['width']:.3f}, "
                              f"order certainty {state['certainty']:.3f}, {state['judgements']} "
                              f"answered main trials")
        if study.stopped:
            self.stdout.write(f"stopped by {study.stopped['rule']}: {study.stopped['value']}; "
                              f"places closed. {study.stopped.get('platform', '')}".rstrip())
