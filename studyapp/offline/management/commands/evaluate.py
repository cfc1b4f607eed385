import json
import math
from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from motion.datasets import DatasetError, get_dataset
from motion.formats import npz
from generation.methods import CheckpointError, load_checkpoint
from motion.motion import MotionError
from motion_metrics.recognition import ActionClassifier, ClassifierError
from generation.sampling import split_names
from motion_metrics.evaluate import (
    LOWER_IS_BETTER, METRICS, PROTOCOLS, EvaluationError, evaluate, evaluate_model, read_extras,
)


class Command(BaseCommand):
    help = (
        "Compute the seeds' objective metrics (FID, accuracy, diversity, multimodality, "
        "MMD_avg, MMD_seq, APD, n-APD, mode homogeneity, dist_e) of an interchange .npz "
        "against a dataset's real clips: mean and 95 % CI over repeats, Real beside."
    )

    def add_arguments(self, parser):
        parser.add_argument("--dataset", required=True, help="Dataset the motions imitate.")
        parser.add_argument("--data-root", help="Folder of the dataset (default: its usual place).")
        parser.add_argument("--motions",
                            help="Interchange .npz (from `sample`; required by the bootstrap "
                                 "protocol); an optional array 'end_targets' (N, D) enables dist_e.")
        parser.add_argument("--checkpoint",
                            help="Checkpoint of the model that made the motions. With modes (odmo), "
                                 "mode_homogeneity groups the real test clips by the modes of their "
                                 "codes (seed 001, Sec. 4.3.1; without it, it is skipped); the a2m "
                                 "protocol samples from it.")
        parser.add_argument("--protocol", choices=sorted(PROTOCOLS), default="bootstrap",
                            help="bootstrap (default): the --motions file resampled per repeat, Real "
                                 "= held-out vs training clips. a2m (Action2Motion's): --n fresh "
                                 "motions sampled from --checkpoint per repeat, Real = two draws of "
                                 "the held-out clips.")
        parser.add_argument("--n", type=int, default=3000,
                            help="a2m: motions sampled per repeat, spread over the actions (A2M: 3,000).")
        parser.add_argument("--classifier",
                            help="Classifier checkpoint (from `train_classifier`); without it fid, "
                                 "accuracy, diversity and multimodality are skipped.")
        parser.add_argument("--metrics", help=f"Comma-separated, from: {', '.join(METRICS)} (default: all).")
        parser.add_argument("--repeats", type=int, default=20, help="Repeats for the 95 %% CI (A2M: 20).")
        parser.add_argument("--seed", type=int, default=0, help="Seed of the repeats' draws.")
        parser.add_argument("--mmd-protocol", choices=("heldout", "paper", "authors"), default="heldout",
                            help="How MMD_avg/MMD_seq are measured: heldout (default: the repeats' "
                                 "draws against every held-out clip of the action, raw coordinates), "
                                 "paper (against the training clips, coordinates standardised by "
                                 "them, equal counts per action) or authors (SA-GCN's code: "
                                 "hip-centred, depth-scaled, 100 per class, against the training "
                                 "clips and, beside, the held-out clips); the output names it.")
        parser.add_argument("--json", required=True, help="File to write the results to.")

    def handle(self, *args, **options):
        if options["repeats"] < 1:
            raise CommandError(f"--repeats must be at least 1; got {options['repeats']}")
        try:
            dataset = get_dataset(options["dataset"], options["data_root"])
        except KeyError as exc:
            raise CommandError(exc.args[0]) from None
        a2m = options["protocol"] == "a2m"
        if a2m and (not options["checkpoint"] or options["motions"]):
            raise CommandError("--protocol a2m samples fresh motions from --checkpoint CKPT in every "
                               "repeat: pass --checkpoint and no --motions")
        if not a2m and not options["motions"]:
            raise CommandError("pass --motions F.npz (or --protocol a2m --checkpoint CKPT)")
        if a2m and options["mmd_protocol"] in ("paper", "authors"):
            raise CommandError(f"--mmd-protocol {options['mmd_protocol']} measures one set of motions: "
                               f"use it with --motions (the bootstrap protocol), not --protocol a2m")
        if a2m and options["n"] < 1:
            raise CommandError(f"--n must be at least 1; got {options['n']}")
        source = options["checkpoint"] if a2m else options["motions"]
        try:
            classifier = ActionClassifier.load(options["classifier"]) if options["classifier"] else None
            metrics = split_names(options["metrics"]) or None
            if a2m:
                model = load_checkpoint(options["checkpoint"], skeleton=dataset.skeleton)
                result = evaluate_model(
                    dataset, model, classifier, metrics, options["repeats"], options["seed"],
                    n=options["n"], frames=classifier.frames if classifier else None,
                    real_modes=getattr(model, "clip_modes", None),
                )
            else:
                motions = npz.load(options["motions"])
                extras = read_extras(options["motions"])
                result = evaluate(
                    dataset, motions, classifier, metrics, options["repeats"], options["seed"],
                    real_modes=self._real_modes(options["checkpoint"], dataset),
                    end_targets=extras.get("end_targets"), mmd_protocol=options["mmd_protocol"],
                )
        except (npz.FormatError, CheckpointError) as exc:
            raise CommandError(str(exc)) from None
        except (EvaluationError, ClassifierError, DatasetError, MotionError) as exc:
            raise CommandError(f"cannot evaluate {source}: {exc}") from None
        result["motions"] = None if a2m else str(options["motions"])
        result["checkpoint"] = options["checkpoint"]
        result["classifier_path"] = options["classifier"]
        out = Path(options["json"])
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2, allow_nan=False) + "\n")
        self.stdout.write(self._table(result))
        self.stdout.write(f"wrote {out}")

    @staticmethod
    def _real_modes(path, dataset):
        """Return the model's ``clip_modes`` (real clips -> modes), or ``None`` without a checkpoint."""
        if not path:
            return None
        model = load_checkpoint(path, skeleton=dataset.skeleton)
        if not hasattr(model, "clip_modes"):
            raise CommandError(f"--checkpoint {path} is a {model.name} model, which has no modes; "
                               f"pass an odmo checkpoint or leave --checkpoint out")
        return model.clip_modes

    def _table(self, result) -> str:
        lines = [
            f"{result['n_motions']} {result['source']} motions"
            f"{' per repeat' if result['protocol']['name'] == 'a2m' else ''} vs {result['dataset']} "
            f"({result['real']['split']}: {result['real']['n_test']} test, "
            f"{result['real']['n_train']} train clips); {result['repeats']} repeats, 95 % CI",
            f"protocol {result['protocol']['name']}: {result['protocol']['description']}",
            f"MMD protocol {result['mmd_protocol']['name']}: {result['mmd_protocol']['description']}",
            f"{'metric':<18}{'motions':>24}{'real':>24}",
        ]
        for name, row in result["metrics"].items():
            arrow = " (lower is better)" if name in LOWER_IS_BETTER else ""
            label = f"{name} [{result['mmd_protocol']['name']}]" if name.startswith("mmd_") else name
            lines.append(f"{label:<18}{_cell(row):>24}{_cell(row['real']):>24}{arrow}")
            if row.get("heldout"):  # the authors' protocol: the same motions against held-out clips
                lines.append(f"{'  held-out clips':<18}{_cell(row['heldout']):>24}")
        for name, reason in result["skipped"].items():
            hint = (": pass --classifier" if "classifier" in reason
                    else ": pass --checkpoint" if "mode of each real" in reason else "")
            lines.append(f"skipped {name}: {reason}{hint}")
        return "\n".join(lines)


def _cell(summary) -> str:
    if not summary or summary["mean"] is None or not math.isfinite(summary["mean"]):
        return "-"
    if summary.get("ci") is None:
        return f"{summary['mean']:.4g}"
    return f"{summary['mean']:.4g} ± {summary['ci']:.2g}"
