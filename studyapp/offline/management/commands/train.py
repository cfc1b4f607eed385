from django.core.management.base import BaseCommand, CommandError

from motion.datasets import DatasetError
from generation.methods import CheckpointError, MethodError, list_methods
from generation.methods.schedule import SCHEDULES
from generation.methods.training import train_on_dataset
from generation.sampling import SamplingError


class Command(BaseCommand):
    help = (
        "Train a generative method on a dataset and write its checkpoint (config, weights, "
        "optimizer state, data statistics). With --resume, continue from --out if it exists."
    )

    def add_arguments(self, parser):
        parser.add_argument("method", help=f"Method key: {', '.join(list_methods())}.")
        parser.add_argument("--dataset", required=True, help="Dataset name (see `datasets`).")
        parser.add_argument("--data-root", help="Folder of the dataset (default: its usual place).")
        parser.add_argument("--subjects", help="Comma-separated subjects, e.g. S1,S5 (default: all).")
        parser.add_argument("--actions", help="Comma-separated actions (default: all).")
        parser.add_argument("--iters", type=int, default=1000,
                            help="Total training iterations; with --resume, train up to this many.")
        parser.add_argument("--preset", default="paper",
                            help="Config preset: paper (the paper's values), demo, or tiny (tests).")
        parser.add_argument("--schedule", choices=sorted(SCHEDULES), default="full",
                            help="How a first training phase (the GAN baselines' pretraining, "
                                 "ODMO's teacher forcing) meets --iters: full keeps the preset's "
                                 "phase and refuses fewer iterations; benchmark shortens it to its "
                                 "share of --iters, as compare_methods trains.")
        parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                            help="Change a config field of the preset, e.g. --set init=he "
                                 "--set mismatch_weight=1 (sa_gcn's departures from the paper); "
                                 "kept in the checkpoint's config. Repeat for several.")
        parser.add_argument("--seed", type=int, default=0, help="Seed of initialisation and batches.")
        parser.add_argument("--frames", type=int, help="Clip length (default: the dataset's).")
        parser.add_argument("--fps", type=float, help="Frame rate (default: the dataset's).")
        parser.add_argument("--resume", action="store_true",
                            help="Continue from --out if it exists (its config and actions win).")
        parser.add_argument("--save-every", type=int, default=500,
                            help="Also write the checkpoint every this many iterations (0: only at the end).")
        parser.add_argument("--out", required=True, help="Checkpoint file to write (.pt).")

    def handle(self, *args, **options):
        if options["iters"] < 0:
            raise CommandError(f"--iters must be non-negative; got {options['iters']}")
        changes = parse_settings(options["set"])
        try:
            model = train_on_dataset(
                options["method"], options["dataset"], options["out"],
                data_root=options["data_root"], subjects=options["subjects"],
                actions=options["actions"], iters=options["iters"], preset=options["preset"],
                seed=options["seed"], frames=options["frames"], fps=options["fps"],
                resume=options["resume"], progress=options["verbosity"] >= 1,
                save_every=options["save_every"], schedule=options["schedule"],
                changes=changes,
            )
        except KeyError as exc:
            raise CommandError(exc.args[0]) from None
        except (DatasetError, MethodError, CheckpointError, SamplingError, ValueError) as exc:
            raise CommandError(str(exc)) from None
        losses = ", ".join(f"{k} {v:.4g}" for k, v in model.losses.items())
        self.stdout.write(
            f"wrote {options['out']}: {model.name} on {model.skeleton}, {len(model.actions)} "
            f"actions, {model.iteration} iterations{f' ({losses})' if losses else ''}"
        )


def parse_settings(items) -> dict:
    """Return ``{field: value}`` of ``--set FIELD=VALUE`` items (values read as JSON: true,
    1, 0.5; anything else is text)."""
    import json

    out = {}
    for item in items:
        name, sep, raw = item.partition("=")
        if not sep or not name.strip():
            raise CommandError(f"--set {item!r}: give FIELD=VALUE, e.g. --set init=he")
        try:
            value = json.loads(raw)
        except ValueError:
            value = raw
        out[name.strip()] = value
    return out
