from django.core.management.base import BaseCommand, CommandError

from motion.datasets import DatasetError
from motion_metrics.recognition import (
    EVAL_EVERY,
    PATIENCE,
    VALIDATION_FRACTION,
    ClassifierConfig,
    ClassifierError,
    train_classifier,
)
from generation.sampling import SamplingError


class Command(BaseCommand):
    help = (
        "Train the GRU action classifier whose 30-d features the FID, diversity and "
        "multimodality metrics use; report its accuracy on held-out clips and write the "
        "checkpoint (config, actions, skeleton, clip length, input statistics, split)."
    )

    def add_arguments(self, parser):
        parser.add_argument("--dataset", required=True, help="Dataset name (see `datasets`).")
        parser.add_argument("--data-root", help="Folder of the dataset (default: its usual place).")
        parser.add_argument("--subjects",
                            help="Comma-separated training subjects (default: all not held out).")
        parser.add_argument("--test-subjects",
                            help="Comma-separated held-out subjects (default: the last fifth, e.g. "
                                 "S9,S11 for h36m). Datasets without subjects hold out a seeded "
                                 "20 %% of each action's takes.")
        parser.add_argument("--actions", help="Comma-separated actions (default: all).")
        parser.add_argument("--frames", type=int, help="Clip length (default: the dataset's).")
        parser.add_argument("--fps", type=float, help="Frame rate (default: the dataset's).")
        parser.add_argument("--iters", type=int, default=2000,
                            help="Most training iterations (early stopping may end sooner).")
        parser.add_argument("--patience", type=int, default=PATIENCE,
                            help="Stop after this many validation measurements without "
                                 "improvement; 0 runs all --iters (the best state is kept either way).")
        parser.add_argument("--eval-every", type=int, default=EVAL_EVERY,
                            help="Iterations between validation measurements.")
        parser.add_argument("--validation", type=float, default=VALIDATION_FRACTION,
                            help="Share of each action's training takes set aside to validate on.")
        parser.add_argument("--preset", default="augmented",
                            help=f"Config preset: {', '.join(sorted(ClassifierConfig.PRESETS))} "
                                 f"(paper: A2M's 2-layer GRU of 128; augmented: the same network trained on "
                                 f"mirrored and slightly rotated clips; tiny: tests).")
        parser.add_argument("--seed", type=int, default=0,
                            help="Seed of initialisation, batches and the take split.")
        parser.add_argument("--out", required=True, help="Checkpoint file to write (.pt).")

    def handle(self, *args, **options):
        if options["iters"] < 1:
            raise CommandError(f"--iters must be at least 1; got {options['iters']}")
        if options["patience"] < 0:
            raise CommandError(f"--patience must be 0 (off) or more; got {options['patience']}")
        if options["eval_every"] < 1:
            raise CommandError(f"--eval-every must be at least 1; got {options['eval_every']}")
        if not 0 < options["validation"] < 1:
            raise CommandError(f"--validation must be between 0 and 1; got {options['validation']}")
        try:
            model = train_classifier(
                options["dataset"], options["out"], data_root=options["data_root"],
                subjects=options["subjects"], test_subjects=options["test_subjects"],
                actions=options["actions"], frames=options["frames"], fps=options["fps"],
                iters=options["iters"], preset=options["preset"], seed=options["seed"],
                progress=options["verbosity"] >= 1, patience=options["patience"] or None,
                eval_every=options["eval_every"], validation=options["validation"],
            )
        except KeyError as exc:
            raise CommandError(exc.args[0]) from None
        except (DatasetError, ClassifierError, SamplingError, ValueError) as exc:
            raise CommandError(str(exc)) from None
        self.stdout.write(
            f"wrote {options['out']}: classifier of {len(model.actions)} actions on "
            f"{model.dataset} ({model.skeleton}, {model.frames} frames at {model.fps:g} fps), "
            f"{model.iteration} iterations; test accuracy {model.test_accuracy:.3f} on "
            f"{model.n_test} held-out clips ({model.split.describe()}), train accuracy "
            f"{model.train_accuracy:.3f} on {model.n_train}"
        )
        self.stdout.write(
            f"kept iteration {model.best_iteration}: validation accuracy "
            f"{model.validation_accuracy:.3f} on {model.n_validation} clips"
            + (" (stopped early on patience)" if model.stopped_early else "")
        )
        self.stdout.write("held-out confusion matrix (rows: true action, columns: predicted):")
        self.stdout.write(model.confusion_text())
