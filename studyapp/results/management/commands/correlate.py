from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from django.core.management.base import BaseCommand, CommandError

from analysis.correlate import correlate, human_draws, write_correlation_report
from analysis.formatting import interval, number
from analysis.study import AnalysisConfig, analyse, analyse_all
from analysis.tables import AnalysisError
from studyapp.results.export import get_study, responses_frame
from studyapp.results.study_motions import MotionsUnavailable, study_motions

# The metrics set beside the human scores (those the seeds report per method).
METRICS = ("fid", "accuracy", "diversity", "multimodality", "mmd_avg", "mmd_seq", "apd")


class Command(BaseCommand):
    help = (
        "Put each method's human score (the study's own analysis) beside its objective "
        "metrics measured on the same motions the study showed, with Spearman and Kendall "
        "rank correlations and bootstrap intervals: report.html, correlations.csv/.md, "
        "one scatter figure per metric (PNG, SVG)."
    )

    def add_arguments(self, parser):
        parser.add_argument("--study", required=True, metavar="SLUG")
        parser.add_argument("--out", required=True, metavar="DIR")
        parser.add_argument("--classifier", metavar="CKPT",
                            help="Action classifier (from train_classifier) for fid, accuracy, "
                                 "diversity and multimodality; without it they are skipped.")
        parser.add_argument("--dataset", help="Dataset of the real clips (default: the study's).")
        parser.add_argument("--data-root", help="Folder of the dataset (default: its usual place).")
        parser.add_argument("--bootstrap", type=int, default=200, metavar="N",
                            help="Bootstrap draws: participants resampled for the human side, "
                                 "each source's motions for the metrics (default 200; 0 = none).")
        parser.add_argument("--seed", type=int, default=0, help="Seed of the bootstrap.")
        parser.add_argument("--manifest", metavar="FILE",
                            help="The study's manifest.json (default: where build_stimuli writes it).")
        parser.add_argument("--cache", metavar="DIR",
                            help="The build's cache folder (default: the manifest's folder, then "
                                 "the shared cache).")
        parser.add_argument("--no-exclusions", action="store_true",
                            help="Keep participants who failed catch trials and too-fast answers.")
        parser.add_argument("--min-time-factor", type=float, default=1.0, metavar="F",
                            help="Exclude trials answered in less than F x the clip length (default 1).")

    def handle(self, *args, study, out, **options):
        if options["bootstrap"] < 0:
            raise CommandError(f"--bootstrap must be 0 or more; got {options['bootstrap']}")
        record = get_study(study)
        table = responses_frame(record)
        if table.empty:
            raise CommandError(f"Study {study} has no answers yet; collect answers (or run "
                               f"simulate_participants) before correlating.")
        try:
            motions = study_motions(record, options["manifest"], options["cache"])
        except MotionsUnavailable as exc:
            raise CommandError(f"Cannot read back the motions of study {study}: {exc}.") from None
        dataset = options["dataset"] or record.dataset
        if not dataset:
            raise CommandError(f"Study {study} names no dataset; pass --dataset D (the dataset "
                               f"its methods were trained on).")
        classifier = self._classifier(options["classifier"], dataset)
        n = options["bootstrap"]
        config = AnalysisConfig(exclusions=not options["no_exclusions"], bootstrap=n,
                                min_time_factor=options["min_time_factor"], seed=options["seed"],
                                max_failed_catch=record.max_failed_catch,
                                type_options=dict(record.options or {}))
        try:
            results = analyse_all(table, config)
        except AnalysisError as exc:
            raise CommandError(f"Cannot analyse {study}: {exc}") from None
        result = results[0]
        notes = list(result.notes)
        if len(results) > 1:
            notes.append(f"the study asked {len(results)} questions; the human score is the "
                         f"first's ({result.criterion})")
        sources = result.analysis.sources
        human = sources[["score", "ci_low", "ci_high"]]
        for name in motions.real:
            if name in human.index:
                notes.append(f"{name} (real clips) is not a method and is left out of the "
                             f"correlations; its human score is {number(human.loc[name, 'score'])}")
        generated = [s for s in motions.generated if s in human.index]
        unjudged = sorted(set(motions.generated) - set(generated))
        if unjudged:
            notes.append(f"no human score (no analysed judgements) for {', '.join(unjudged)}")
        if not generated:
            raise CommandError(f"Study {study}: none of its methods "
                               f"({', '.join(motions.generated)}) has analysed judgements.")
        draws = None
        if n:
            single = replace(config, bootstrap=0)

            def score_of(rows):
                return analyse(rows, single, criterion=result.criterion).analysis.sources["score"]

            draws = human_draws(table, score_of, n, options["seed"])
            if draws.attrs.get("failed"):
                notes.append(f"{draws.attrs['failed']} of {n} resamples of participants could "
                             f"not be analysed and are left out of the intervals")
        values, per_draw, real, skipped, details = self._metrics(
            motions.generated, generated, dataset, options["data_root"], classifier,
            n or 20, options["seed"])
        notes += [f"{name} skipped: {reason}" for name, reason in skipped.items()]
        try:
            measured = pd.DataFrame(values).T.loc[generated].astype(float)
            outcome = correlate(human.loc[generated], measured,
                                real=real, human_draws=draws, metric_draws=per_draw if n else None,
                                human_measure=result.analysis.measure)
        except AnalysisError as exc:
            raise CommandError(f"Cannot correlate {study}: {exc}") from None
        outcome.notes = notes + outcome.notes
        written = write_correlation_report(
            outcome, Path(out), title=f"{study}: human scores and objective metrics",
            details=details)
        self._print(study, outcome, written, Path(out))

    def _classifier(self, path, dataset):
        if not path:
            return None
        from motion_metrics.recognition import ActionClassifier, ClassifierError

        fix = (f"train one: manage.py train_classifier --dataset {dataset} --frames T --out {path} "
               f"(T: the study's clip length in frames), or leave --classifier out to skip fid, "
               f"accuracy, diversity and multimodality")
        if not Path(path).is_file():
            raise CommandError(f"No classifier at --classifier {path}; {fix}.")
        try:
            return ActionClassifier.load(path)
        except (ClassifierError, OSError, ValueError, KeyError) as exc:
            raise CommandError(f"Cannot load the classifier {path}: {exc}; {fix}.") from None

    def _metrics(self, motions, sources, dataset, data_root, classifier, repeats, seed):
        """Return per source the metrics' values (the protocol's mean over resamples of its
        motions), per metric a (repeats, sources) frame of the resamples, the real clips'
        values, the skipped metrics and sentences for the methods paragraph."""
        from motion_metrics.evaluate import EvaluationError, evaluate

        values, draws, real, skipped = {}, {}, {}, {}
        for source in sources:
            try:
                found = evaluate(dataset, motions[source], classifier, METRICS, repeats, seed,
                                 data_root=data_root)
            except (EvaluationError, ValueError) as exc:
                raise CommandError(f"Cannot measure source {source!r}: {exc}") from None
            skipped.update(found["skipped"])
            values[source] = {name: row["mean"] for name, row in found["metrics"].items()}
            for name, row in found["metrics"].items():
                draws.setdefault(name, {})[source] = row["values"]
                if row["real"] and row["real"]["mean"] is not None:
                    real.setdefault(name, []).append(row["real"]["mean"])
            split = found["real"]["split"]
        frames = {name: pd.DataFrame(columns, dtype=float) for name, columns in draws.items()}
        real = {name: float(np.mean(v)) for name, v in real.items()}
        hint = " (pass --classifier)" if any("classifier" in r for r in skipped.values()) else ""
        skipped = {name: reason + hint for name, reason in skipped.items()}
        details = [
            f"Metrics were measured on the judged motions of each method, read back from the "
            f"study's build, against the real clips of dataset {dataset} ({split}); each value "
            f"is the mean over {repeats} resamples (with replacement) of the method's motions, "
            f"as `evaluate` reports it. Diversity, multimodality and APD count as better the "
            f"closer they are to the real clips' value."
        ]
        return values, frames, real, skipped, details

    def _print(self, study, outcome, written, out):
        self.stdout.write(f"Study {study}: {len(outcome.sources)} methods, human score: "
                          f"{outcome.human_measure}.")
        metrics = list(outcome.table["metric"])
        for source, row in outcome.sources.sort_values("score", ascending=False).iterrows():
            values = ", ".join(f"{name} {row[name]:.4g}" for name in metrics
                               if np.isfinite(row[name]))
            self.stdout.write(f"  {source}: {number(row['score'])} "
                              f"{interval(row['ci_low'], row['ci_high'])}; {values}")
        self.stdout.write("Rank correlations with each metric's goodness (+1: the metric "
                          "orders the methods as the participants did):")
        for row in outcome.table.itertuples():
            self.stdout.write(
                f"  {row.metric:<14} ({row.direction}): Spearman {number(row.spearman, 2)} "
                f"{interval(row.spearman_low, row.spearman_high, 2)} (permutation p "
                f"{number(row.spearman_p, 3)}), Kendall {number(row.kendall, 2)} "
                f"{interval(row.kendall_low, row.kendall_high, 2)} (p {number(row.kendall_p, 3)})")
        for note in outcome.notes:
            self.stderr.write(self.style.WARNING(f"Note: {note}."))
        figures = sum(1 for path in written if path.suffix == ".png")
        self.stdout.write(f"Wrote report.html, correlations.csv/.md/.tex and {figures} scatter "
                          f"figures (PNG, SVG) to {out}.")
