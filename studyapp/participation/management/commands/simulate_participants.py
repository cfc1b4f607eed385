import random
import secrets
from concurrent.futures import ThreadPoolExecutor

from django.core.management.base import BaseCommand, CommandError
from django.db import close_old_connections

from studyapp.participation.bots import (
    POLICIES,
    Bot,
    SimulationError,
    entry_url,
    parse_strengths,
    person_id,
)
from studyapp.results.export import get_study
from studyapp.survey.models import Participant, Stimulus


class Command(BaseCommand):
    help = (
        "Play a study through its real pages with N simulated participants (bots), several "
        "at once. Each bot fetches every clip as a browser does and waits as long as the "
        "clips play (the server refuses answers sooner). Policies: random, prefer-real, bt "
        "(Bradley-Terry strengths per source), inattentive (fails every catch trial and "
        "instructed check), decline (no consent), screen-out (fails the screening "
        "questions); see "
        "studyapp/participation/bots.py. Sources come from the database, never the page."
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
            "--clip-sd", type=float, default=0.0, metavar="SD",
            help="bt: clips vary about their source, each clip's log strength its source's "
                 "plus a fixed normal draw of this SD (from the clip's id and --clip-seed; "
                 "default 0: every clip of a source alike).")
        parser.add_argument("--clip-seed", type=int, default=0,
                            help="bt with --clip-sd: the seed of the clips' draws.")
        parser.add_argument(
            "--pace", type=float, default=1.0, metavar="FACTOR",
            help="Wait FACTOR x the longest clip before each answer (at least 1: the server "
                 "takes no answer before the clips could have played through).",
        )
        parser.add_argument("--concurrency", type=int, default=8,
                            help="Bots taking the study at the same time.")
        parser.add_argument("--no-watch", action="store_true",
                            help="Answer without fetching the clips or waiting (the server "
                                 "refuses these bots: a check of the watch rule).")

    def handle(self, *args, study, n, url, policy, seed, strengths, pace, concurrency,
               no_watch, clip_sd=0.0, clip_seed=0, **options):
        study = get_study(study)
        if n < 1 or pace < 0 or concurrency < 1:
            raise CommandError("--n and --concurrency must be at least 1 and --pace at least 0")
        if clip_sd < 0 or (clip_sd and policy != "bt"):
            raise CommandError("--clip-sd must be at least 0, and is for the bt policy only")
        clips = {"clip_sd": clip_sd, "clip_seed": clip_seed} if clip_sd else {}
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

        def one(i):
            rng = random.Random(f"{run}-{i}")
            bot = Bot(study, POLICIES.get(policy)(rng, strengths, sources, **clips), rng, pace=pace,
                      watch=not no_watch)
            person = person_id(run, i)
            try:
                return person, bot.run(entry_url(study, url, person)), None
            except SimulationError as error:
                return person, None, error
            finally:
                close_old_connections()

        failures = 0
        with ThreadPoolExecutor(max_workers=min(concurrency, n)) as pool:
            for person, outcome, error in pool.map(one, range(1, n + 1)):
                if error is not None:
                    failures += 1
                    self.stderr.write(f"{person}: {error}")
                    continue
                kind = Participant.objects.filter(
                    study=study, external_key__endswith=f":{person}"
                ).values_list("outcome", flat=True).first() or ""
                redirect = f", redirect {outcome.exit_url}" if outcome.exit_url else ""
                self.stdout.write(f"{person}: {outcome.trials} trials, outcome {kind}{redirect}, "
                                  f"completion code {outcome.completion_code}")
        done = n - failures
        self.stdout.write(
            f"{done} of {n} simulated participants completed {study.slug} ({policy})."
        )
        if failures:
            raise CommandError(f"{failures} of {n} simulated participants did not finish")
