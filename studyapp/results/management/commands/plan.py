from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from analysis import plan
from analysis.simulate import STUDY_TYPES
from analysis.study import AnalysisConfig, analyse
from analysis.tables import AnalysisError, read_responses
from studyapp.participation.duration import session_seconds
from studyapp.results.export import get_study
from studyapp.survey.models import Trial

MAIN = str(Trial.Kind.MAIN)


def _study_session(slug):
    """Return the study ``slug`` and its duration model's parts: the seconds of the pages
    around the trials, each planned trial's kind and seconds, and its ``Duration``."""
    study = get_study(slug)
    fixed, trials = session_seconds(study)
    return study, (fixed, trials, study.duration())


def _numbers(text):
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise CommandError(f"{text!r}: give whole numbers separated by commas, e.g. 20,40,80") from None
    if not values or min(values) < 1:
        raise CommandError(f"{text!r}: give whole numbers of 1 or more, e.g. 20,40,80")
    return values


class Command(BaseCommand):
    help = (
        "Plan a study: the power to tell two sources apart, and the width of the interval of "
        "their difference, for a grid of participants x clips per source and condition, by "
        "simulation through the study's own analysis (participants and clips random) or from a "
        "pilot's responses; with minutes per participant (from an existing study's duration "
        "model with --study, else from --trials and --clip-seconds) and the Prolific cost. "
        "Writes plan.csv and power.png with --out."
    )

    def add_arguments(self, parser):
        parser.add_argument("--type", dest="study_type", choices=STUDY_TYPES,
                            help="Study type to simulate (without --pilot; default the "
                                 "--study's).")
        parser.add_argument("--study", metavar="SLUG",
                            help="Plan for this existing study: its type, its main trials per "
                                 "participant, and minutes from its duration model (a session "
                                 "planned as a participant's would be, its clips' lengths and "
                                 "the type's answer time; the measured median once enough "
                                 "participants completed).")
        parser.add_argument("--pilot", metavar="FILE",
                            help="A pilot's exported responses (CSV or Parquet): plan from its "
                                 "estimated variance shares instead of assumptions.")
        parser.add_argument("--sources", default="a,b", metavar="A,B",
                            help="With --pilot: the two sources to tell apart (default a,b).")
        parser.add_argument("--effect", type=float, default=None,
                            help="Strength of A above B (logit scale; default 0.5), or with "
                                 "--pilot the difference to detect on the pilot's scale "
                                 "(default: the pilot's own).")
        parser.add_argument("--clip-sd", type=float, default=0.5,
                            help="SD of clip quality about its source's strength (logit scale).")
        parser.add_argument("--noise", type=float, default=1.0, help="Noise of single answers.")
        parser.add_argument("--conditions", type=int, default=1, help="Actions or prompts.")
        parser.add_argument("--trials", type=int, default=None,
                            help="Main trials per participant (default the --study's, else 10).")
        parser.add_argument("--clips-per-trial", type=int, default=2,
                            help="Clips per trial (for types that show several clips a trial).")
        parser.add_argument("--participants", default="20,40,80", metavar="N,N,...")
        parser.add_argument("--clips", default="2,4,8", metavar="M,M,...",
                            help="Clips per source and condition to try.")
        parser.add_argument("--studies", type=int, default=50,
                            help="Simulated studies per design (default 50).")
        parser.add_argument("--bootstrap", type=int, default=100,
                            help="Bootstrap resamples per simulated study's analysis.")
        parser.add_argument("--target", type=float, default=0.8, help="Power to reach.")
        parser.add_argument("--alpha", type=float, default=0.05)
        parser.add_argument("--clip-seconds", type=float, default=3.0,
                            help="Length of a clip, for the minutes per participant (without "
                                 "--study, or when the study has no trials yet).")
        parser.add_argument("--reward-per-hour", type=float, default=12.0,
                            help="Reward per hour in the study's currency (default 12.00).")
        parser.add_argument("--service-fee", type=float, default=plan.PROLIFIC_SERVICE_FEE,
                            help="Prolific's service fee as a share of rewards (default "
                                 f"{plan.PROLIFIC_SERVICE_FEE}: its academic rate when "
                                 "written, VAT not included; give your workspace's).")
        parser.add_argument("--seed", type=int, default=0)
        parser.add_argument("--out", metavar="DIR", help="Write plan.csv and power.png here.")

    def handle(self, *args, **options):
        participants = _numbers(options["participants"])
        clips = _numbers(options["clips"])
        study, session = None, None
        if options["study"]:
            study, session = _study_session(options["study"])
            if not options["study_type"] and not options["pilot"]:
                if study.study_type not in STUDY_TYPES:
                    raise CommandError(f"study {study.slug}'s type has no simulation to plan "
                                       f"from; give --pilot FILE")
                options["study_type"] = study.study_type
        if options["trials"] is None and session is not None:
            options["trials"] = sum(1 for kind, _ in session[1] if kind == MAIN) or None
        given_trials = options["trials"]
        if options["trials"] is None:
            options["trials"] = 10
        try:
            if options["pilot"]:
                a, _, b = options["sources"].partition(",")
                pilot = analyse(read_responses(options["pilot"]), AnalysisConfig(seed=options["seed"]))
                components = plan.pilot_components(pilot, a.strip(), b.strip())
                frame = plan.pilot_power(components, participants, clips, options["effect"],
                                         options["alpha"])
                trials = round(components["trials"])
                source = (f"from the pilot ({components['participants']} participants, "
                          f"{components['clips']:g} clips per source and condition): "
                          f"{a} - {b} = {components['difference']:.3g}, se "
                          f"{components['se']:.3g}, variance {components['share_clips']:.0%} "
                          f"from clips")
            else:
                if not options["study_type"]:
                    raise CommandError("give --type (to simulate) or --pilot FILE")
                assumptions = plan.Assumptions(
                    options["study_type"], effect=0.5 if options["effect"] is None else options["effect"],
                    clip_sd=options["clip_sd"], noise=options["noise"], trials=options["trials"],
                    conditions=options["conditions"], clips_per_trial=options["clips_per_trial"])
                frame = plan.simulated_power(assumptions, participants, clips, options["studies"],
                                             options["bootstrap"], options["alpha"], options["seed"])
                trials = options["trials"]
                source = (f"by simulation ({options['studies']} studies per design, "
                          f"{assumptions.study_type}, effect {assumptions.effect:g}, clip SD "
                          f"{assumptions.clip_sd:g})")
        except AnalysisError as error:
            raise CommandError(str(error)) from None
        minutes = None
        if study is not None:
            fixed, trials_seconds = session[0], session[1]
            duration = session[2]
            minutes = plan.session_minutes(
                fixed, trials_seconds, given_trials if options["pilot"] is None else trials,
                duration.measured, duration.n_measured, f"study {study.slug}", MAIN)
        if minutes is None:
            minutes = plan.assumed_minutes(trials, options["clip_seconds"])
            if study is not None:
                minutes = plan.Minutes(minutes.minutes, f"{minutes.source} (study {study.slug} "
                                                        f"plans no main trial yet: no clips built?)")
        frame = plan.costs(frame, minutes.minutes, options["reward_per_hour"],
                           options["service_fee"])
        best = plan.recommend(frame, options["target"])
        if not options["pilot"]:
            # The pick's own estimate is biased upward by the picking: measure it again.
            try:
                best = plan.confirm(assumptions, best, options["studies"], options["bootstrap"],
                                    options["alpha"], options["seed"], options["target"])
            except AnalysisError as error:
                raise CommandError(str(error)) from None
        self.stdout.write(f"Power {source}; service fee {options['service_fee']:.1%} of rewards")
        self.stdout.write(f"Minutes per participant: {minutes.minutes:.1f}, {minutes.source}")
        self.stdout.write(frame.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
        self.stdout.write("Recommended: " + plan.advice(best, options["target"], frame))
        if options["out"]:
            out = Path(options["out"])
            out.mkdir(parents=True, exist_ok=True)
            frame.to_csv(out / "plan.csv", index=False)
            plan.power_figure(frame, options["target"]).savefig(out / "power.png", dpi=120)
            self.stdout.write(f"Wrote {out / 'plan.csv'} and {out / 'power.png'}")
