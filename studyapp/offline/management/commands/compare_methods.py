import shlex
from pathlib import Path

from django.conf import settings
from django.core.management.base import BaseCommand, CommandError

from motion.datasets import DatasetError
from generation.methods import CheckpointError, MethodError, list_methods
from motion_metrics.recognition import ClassifierError
from generation.sampling import SamplingError, split_names
from generation.methods.budget import write_json
from motion_metrics.comparison import (
    MMD_PROTOCOL, SELECT_N, SELECTIONS, ComparisonError, Selection, run_comparison,
)
from motion_metrics.comparison_report import render, runs_beside
from motion_metrics.sweep_report import render_sweep
from motion_metrics.protocol import MMD_PROTOCOLS


class Command(BaseCommand):
    help = (
        "Train every method with several seeds for an equal number of iterations (or a time "
        "budget) on each dataset, evaluate each seed's model (its last checkpoint, or with "
        "--select best-mmd-seq the one of lowest MMD_seq) with the seed papers' metrics and "
        "write a Markdown report of the means over seeds, with intervals over seeds and over "
        "samples, beside the papers' numbers (default docs/RESULTS.md). Checkpoints in --work "
        "let a stopped run resume."
    )

    def add_arguments(self, parser):
        parser.add_argument("--dataset", default="h36m2d,h36m",
                            help="Comma-separated datasets: h36m2d (seeds 003/004), h36m (A2M's "
                                 "metrics), demo (default: h36m2d,h36m).")
        budget = parser.add_mutually_exclusive_group(required=True)
        budget.add_argument("--iters",
                            help="Training iterations per method, dataset and seed (the same for "
                                 "every method; phases of pretraining count); several, comma-"
                                 "separated (250,500,1000,2000), run a budget sweep: the report "
                                 "is --main-iters' with a section comparing every budget.")
        budget.add_argument("--budget", type=float,
                            help="Instead of --iters: seconds of training wall time per method, "
                                 "dataset and seed.")
        parser.add_argument("--main-iters", type=int,
                            help="With several --iters: the budget of the report's main tables "
                                 "(default: the largest).")
        parser.add_argument("--seeds", default="0,1,2",
                            help="Comma-separated training seeds, at least 2 for an interval over "
                                 "seeds (default: 0,1,2). Each seed's model samples and is "
                                 "evaluated with that seed; the classifier trains with the first.")
        parser.add_argument("--methods", help=f"Comma-separated, from: {', '.join(list_methods())} "
                                              f"(default: all).")
        parser.add_argument("--presets", metavar="METHOD=PRESET,...",
                            help="Config presets replacing the default recipe (demo) of some methods.")
        parser.add_argument("--repeats", type=int, default=20, help="Repeats for the 95 %% CI (A2M: 20).")
        parser.add_argument("--n", type=int, default=100, help="Motions per action (seed 003: 100).")
        parser.add_argument("--subjects", help="Training subjects (default for h36m*: S1,S5,S6,S7,S8).")
        parser.add_argument("--test-subjects", help="Held-out subjects (default for h36m*: S9).")
        parser.add_argument("--actions", help="Comma-separated actions (default: the dataset's).")
        parser.add_argument("--classifier-iters", type=int, default=500,
                            help="Training iterations of the action classifier.")
        parser.add_argument("--classifier-preset", default="augmented",
                            help="Classifier preset: paper (A2M's GRU), augmented (the same GRU "
                                 "trained on mirrored and rotated clips) or tiny (tests).")
        parser.add_argument("--mmd-protocol", choices=sorted(MMD_PROTOCOLS), default=MMD_PROTOCOL,
                            help="How MMD_avg/MMD_seq are measured: heldout (default: against every "
                                 "held-out clip of the action, raw coordinates), paper (against the "
                                 "training clips, coordinates standardised by them, equal paired "
                                 "counts per action) or authors (SA-GCN's code: hip-centred, "
                                 "depth-scaled poses, 100 per class, against training and held-out "
                                 "clips); every table names it.")
        parser.add_argument("--select", choices=list(SELECTIONS), default="last",
                            help="Which checkpoint of each training is evaluated: last (default) or "
                                 "best-mmd-seq (seeds 003/004: of candidates kept every "
                                 "--select-every iterations within the same budget, and the last, the "
                                 "one with the lowest MMD_seq against the training clips, paper MMD "
                                 "protocol); the training tables show the iteration chosen per seed.")
        parser.add_argument("--select-every", type=int, metavar="N",
                            help="best-mmd-seq: a candidate every N iterations (default with --iters: "
                                 "a tenth of them; required with --budget).")
        parser.add_argument("--select-n", type=int, default=SELECT_N, metavar="M",
                            help=f"best-mmd-seq: motions per action sampled to score a candidate "
                                 f"(default: {SELECT_N}; another seed than the evaluated motions').")
        parser.add_argument("--data-root", help="Folder of the datasets (default: their usual place).")
        parser.add_argument("--work", help="Folder for checkpoints, samples and records "
                                           "(default: STUDY_VAR_DIR/benchmark).")
        parser.add_argument("--out", default="docs/RESULTS.md", help="Markdown file to write.")

    def handle(self, *args, **options):
        if options["budget"] is not None and options["budget"] <= 0:
            raise CommandError(f"--budget must be positive; got {options['budget']}")
        sweep = budgets_of(options)
        main = options["main_iters"] or (max(sweep) if sweep else None)
        if sweep and main not in sweep:
            raise CommandError(f"--main-iters {main} is not one of --iters {options['iters']}")
        if sweep and len(sweep) > 1 and options["select"] != "last":
            raise CommandError("a budget sweep (several --iters) measures the last checkpoints, as "
                               "studies train them; drop --select, or give one --iters")
        options["iters"] = main
        try:
            seeds = [int(seed) for seed in split_names(options["seeds"])]
        except ValueError:
            raise CommandError(f"--seeds {options['seeds']!r}: write comma-separated integers, "
                               f"e.g. 0,1,2") from None
        if len(seeds) < 2 or len(set(seeds)) != len(seeds) or min(seeds) < 0:
            raise CommandError(f"--seeds {options['seeds']!r}: give at least 2 distinct "
                               f"non-negative seeds (an interval over seeds needs 2), e.g. 0,1,2")
        selection = selection_of(options)
        work = Path(options["work"] or Path(settings.VAR_DIR) / "benchmark")
        try:
            presets = dict(item.split("=", 1) for item in split_names(options["presets"]))
        except ValueError:
            raise CommandError(f"--presets {options['presets']!r}: write METHOD=PRESET pairs") from None
        common = dict(
            seeds=seeds, methods=split_names(options["methods"]) or None, presets=presets,
            repeats=options["repeats"], n=options["n"],
            subjects=split_names(options["subjects"]) or None,
            test_subjects=split_names(options["test_subjects"]) or None,
            actions=split_names(options["actions"]) or None,
            classifier_iters=options["classifier_iters"],
            classifier_preset=options["classifier_preset"], data_root=options["data_root"],
            mmd_protocol=options["mmd_protocol"], selection=selection,
            progress=options["verbosity"] >= 1, log=self.stdout.write)
        results = []
        try:
            for iters in sweep or [None]:  # shorter budgets first: longer ones resume them
                results.append(run_comparison(split_names(options["dataset"]), options["budget"],
                                             work, iters=iters, **common))
        except KeyError as exc:
            raise CommandError(exc.args[0]) from None
        except (ComparisonError, DatasetError, ClassifierError, MethodError, CheckpointError,
                SamplingError) as exc:
            raise CommandError(str(exc)) from None
        out = Path(options["out"])
        out.parent.mkdir(parents=True, exist_ok=True)
        command = command_line(options, work, selection, sweep)
        if len(results) > 1:
            write_json(work / "sweep.json", {"iters": sweep, "main": main, "results": results})
            out.write_text(render_sweep(results, command, main, runs_beside(out)))
        else:
            out.write_text(render(results[0], command, runs_beside(out)))
        minutes = sum(result["wall_seconds"] for result in results) / 60
        self.stdout.write(f"wrote {out} ({minutes:.1f} minutes)")


def budgets_of(options: dict) -> list[int] | None:
    """Return the --iters budgets in increasing order (None with --budget), checked."""
    if options["iters"] is None:
        return None
    try:
        budgets = sorted({int(value) for value in split_names(options["iters"])})
    except ValueError:
        raise CommandError(f"--iters {options['iters']!r}: write a number of iterations, or several "
                           f"comma-separated (250,500,1000)") from None
    if not budgets or budgets[0] < 1:
        raise CommandError(f"--iters must be at least 1; got {options['iters']}")
    return budgets


def selection_of(options: dict) -> Selection:
    """Return the checkpoint selection asked for, or raise a CommandError naming the option."""
    every, iters = options["select_every"], options["iters"]
    if options["select"] != "best-mmd-seq":
        if every is not None or options["select_n"] != SELECT_N:
            raise CommandError(f"--select-every and --select-n go with --select best-mmd-seq, not "
                               f"--select {options['select']}")
        return Selection(options["select"])
    if every is None:
        if iters is None:
            raise CommandError("--select best-mmd-seq with --budget needs --select-every N "
                               "(candidates every N iterations)")
        every = max(1, iters // 10)
    if every < 1 or (iters is not None and every > iters):
        raise CommandError(f"--select-every must be from 1 to --iters ({iters}); got {every}"
                           if iters is not None else f"--select-every must be at least 1; got {every}")
    if options["select_n"] < 2:
        raise CommandError(f"--select-n must be at least 2 (MMD needs 2 motions a side); "
                           f"got {options['select_n']}")
    return Selection("best-mmd-seq", every, options["select_n"])


def command_line(options: dict, work: Path, selection: Selection, sweep=None) -> str:
    """Return the command that reproduces this run (every choice spelled out)."""
    parts = ["python", "manage.py", "compare_methods", "--dataset", options["dataset"]]
    if sweep and len(sweep) > 1:
        parts += ["--iters", ",".join(map(str, sweep)), "--main-iters", str(options["iters"])]
    elif options["iters"] is not None:
        parts += ["--iters", str(options["iters"])]
    else:
        parts += ["--budget", f"{options['budget']:g}"]
    parts += ["--seeds", ",".join(str(int(seed)) for seed in split_names(options["seeds"]))]
    for flag in ("methods", "presets", "subjects", "test_subjects", "actions", "data_root"):
        if options[flag]:
            parts += [f"--{flag.replace('_', '-')}", options[flag]]
    parts += ["--repeats", str(options["repeats"]),
              "--n", str(options["n"]), "--classifier-iters", str(options["classifier_iters"]),
              "--classifier-preset", options["classifier_preset"],
              "--mmd-protocol", options["mmd_protocol"], "--select", selection.rule]
    if selection.best:
        parts += ["--select-every", str(selection.every), "--select-n", str(selection.n)]
    parts += ["--out", options["out"], "--work", str(work)]
    return shlex.join(parts)
