import random
import secrets

from django.core.management.base import BaseCommand, CommandError

from studyapp.survey.export import get_study
from studyapp.survey.models import Stimulus
from studyapp.survey.simulate import (
    POLICIES,
    Bot,
    SimulationError,
    entry_url,
    parse_strengths,
)


class Command(BaseCommand):
    help = (
        "Play a study through its real pages with N simulated participants (bots). "
        "Policies: random, prefer-real, bt (Bradley-Terry strengths per source; see "
        "studyapp/survey/simulate.py). Sources come from the database, never the page."
    )

    def add_arguments(self, parser):
        parser.add_argument("--study", required=True, metavar="SLUG")
        parser.add_argument("--n", type=int, default=1, help="Number of participants.")
        parser.add_argument(
            "--url", required=True, help="The server (http://127.0.0.1:8000) or a study link."
        )
        parser.add_argument("--policy", choices=sorted(POLICIES), default="random")
        parser.add_argument("--seed", type=int, help="Makes answers and crowd ids repeatable.")
        parser.add_argument(
            "--strengths", default="", metavar="SRC=S,...", help="bt: e.g. real=4,a2m=3,cond_gru=1"
        )
        parser.add_argument(
            "--pace", type=float, default=1.0, metavar="FACTOR",
            help="Wait FACTOR x the longest clip before each answer, as a viewer must (0: none).",
        )

    def handle(self, *args, study, n, url, policy, seed, strengths, pace, **options):
        study = get_study(study)
        if n < 1 or pace < 0:
            raise CommandError("--n must be at least 1 and --pace at least 0")
        try:
            strengths = parse_strengths(strengths)
        except ValueError as error:
            raise CommandError(str(error)) from None
        judged = Stimulus.objects.judged().filter(study=study)
        sources = sorted(set(judged.values_list("source", flat=True)))
        unknown = sorted(set(strengths) - set(sources))
        if unknown:
            raise CommandError(
                f"--strengths names {', '.join(unknown)}, not a source of {study.slug} "
                f"({', '.join(sources)})"
            )
        run = seed if seed is not None else secrets.token_hex(3)
        failures = 0
        for i in range(1, n + 1):
            rng = random.Random(f"{run}-{i}")
            bot = Bot(study, POLICIES[policy](rng, strengths, sources), rng, pace=pace)
            person = f"sim-{run}-{i}"
            try:
                outcome = bot.run(entry_url(study, url, person))
            except SimulationError as error:
                failures += 1
                self.stderr.write(f"{person}: {error}")
                continue
            self.stdout.write(
                f"{person}: {outcome.trials} trials, completion code {outcome.completion_code}"
            )
        done = n - failures
        self.stdout.write(
            f"{done} of {n} simulated participants completed {study.slug} ({policy})."
        )
        if failures:
            raise CommandError(f"{failures} of {n} simulated participants did not finish")
