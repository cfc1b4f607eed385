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
from studyapp.results.study_motions import (MotionsUnavailable, source_checkpoints, source_files,
                                            study_motions)

# The metrics set beside the human scores (those the seeds report per method).
METRICS = ("fid", "accuracy", "diversity", "multimodality", "mmd_avg", "mmd_seq", "apd")
# Fresh motions per method for its metrics (FID in a classifier's feature space of a few
# dozen dimensions needs many more motions than a study shows).
FRESH = 500
# Added to --seed for the fresh sample, so that it does not repeat the build's draws.
FRESH_SEED = 7919


class Command(BaseCommand):
    help = (
        "Put each method's human score (the study's own analysis) beside its objective "
        "metrics, measured on a fresh large sample from the same checkpoint (--fresh N, "
        "default 500; a file source's whole file with --source NAME=FILE) or on the motions "
        "the study showed (--shown-clips), with Spearman and Kendall rank correlations and "
        "bootstrap intervals: report.html, correlations.csv/.md, one scatter figure per "
        "metric (PNG, SVG)."
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
        parser.add_argument("--fresh", type=int, default=FRESH, metavar="N",
                            help=f"Measure each method's metrics on N fresh motions sampled from "
                                 f"its checkpoints in the build manifest (default {FRESH}, "
                                 f"spread over the study's actions); a file source on all "
                                 f"motions of its file (--source NAME=FILE). A source without "
                                 f"either falls back to the clips shown, with a note.")
        parser.add_argument("--shown-clips", action="store_true",
                            help="Measure the metrics on the clips the study showed instead (a "
                                 "few per method: FID and the like are unstable on so few).")
        parser.add_argument("--source", action="append", default=[], metavar="NAME=PATH",
                            help="Where source NAME's checkpoint (or motion file) is, when the "
                                 "build cache does not hold it (a checkpoint the config gave by "
                                 "path); checked against the manifest's sha256. Repeatable.")
        parser.add_argument("--no-exclusions", action="store_true",
                            help="Keep participants who failed catch trials and too-fast answers.")
        parser.add_argument("--min-time-factor", type=float, default=1.0, metavar="F",
                            help="Exclude trials answered in less than F x the clip length (default 1).")

    def handle(self, *args, study, out, **options):
        if options["bootstrap"] < 0:
            raise CommandError(f"--bootstrap must be 0 or more; got {options['bootstrap']}")
        if options["fresh"] < 1 and not options["shown_clips"]:
            raise CommandError(f"--fresh must be 1 or more; got {options['fresh']} (or measure "
                               f"the clips shown: --shown-clips)")
        given = {}
        for item in options["source"]:
            name, sep, path = item.partition("=")
            if not sep or not name.strip() or not path.strip():
                raise CommandError(f"--source {item!r}: give NAME=PATH, e.g. a2m=checkpoints/a2m.pt")
            given[name.strip()] = path.strip()
        record = get_study(study)
        table = responses_frame(record)
        if table.empty:
            raise CommandError(f"Study {study} has no answers yet; collect answers (or run "
                               f"simulate_participants) before correlating.")
        try:
            motions = study_motions(record, options["manifest"], options["cache"])
        except MotionsUnavailable as exc:
            raise CommandError(f"Cannot read back the motions of study {study}: {exc}.") from None
        checkpoints = {}
        if not options["shown_clips"]:
            try:
                checkpoints = source_checkpoints(motions, given)
            except MotionsUnavailable as exc:
                raise CommandError(str(exc)) from None
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
        measured_on, described, sample_notes = self._samples(
            motions, generated, given, checkpoints, options["fresh"], options["shown_clips"],
            options["seed"])
        notes += sample_notes
        values, per_draw, real, skipped, details = self._metrics(
            measured_on, generated, dataset, options["data_root"], classifier,
            n or 20, options["seed"], described)
        notes += [f"{name} skipped: {reason}" for name, reason in skipped.items()]
        try:
            measured = pd.DataFrame(values).T.loc[generated].astype(float)
            outcome = correlate(human.loc[generated], measured,
                                real=real, human_draws=draws, metric_draws=per_draw if n else None,
                                human_measure=result.analysis.measure)
        except AnalysisError as exc:
            raise CommandError(f"Cannot correlate {study}: {exc}") from None
        outcome.notes = notes + outcome.notes
        outcome.sources["metrics_sample"] = pd.Series(described)
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

    def _samples(self, motions, sources, given, checkpoints, fresh, shown_only, seed):
        """Return per source the motions its metrics are measured on, what they are (in
        words) and notes on sources that fell back to the clips shown."""
        shown = {s: motions.generated[s] for s in sources}
        described = {s: f"the {len(shown[s])} clips the study showed" for s in sources}
        if shown_only:
            return shown, described, []
        from generation.sampling import SamplingError, sample_checkpoints
        from generation.methods import CheckpointError, MethodError

        out, notes = dict(shown), []
        for source in sources:
            clips = shown[source]
            if motions.kinds[source] == "method":
                spec = checkpoints.get(source, "the manifest lists none")
                if isinstance(spec, str):
                    notes.append(f"{source}: metrics on {described[source]}, not a fresh sample: "
                                 f"{spec}")
                    continue
                method, paths = spec
                actions = list(dict.fromkeys(m.action for m in clips))
                try:
                    out[source] = sample_checkpoints(paths, actions, fresh, clips[0].frames,
                                                     seed + FRESH_SEED, method)
                except (SamplingError, MethodError, CheckpointError, OSError) as exc:
                    raise CommandError(f"Cannot sample source {source!r} afresh: {exc}; or "
                                       f"measure the clips shown (--shown-clips)") from None
                described[source] = (f"{fresh} fresh motions from its checkpoint"
                                     f"{'s' if len(paths) > 1 else ''} ("
                                     f"{', '.join(Path(p).name for p in paths)}; seed "
                                     f"{seed + FRESH_SEED}, {len(actions)} actions)")
            elif source in given:
                whole = self._file_motions(source, given[source], clips,
                                           source_files(motions).get(source))
                out[source] = whole
                described[source] = f"all {len(whole)} motions of its file {given[source]}"
            else:
                notes.append(f"{source}: metrics on {described[source]}: pass --source "
                             f"{source}=FILE to measure all motions of its file")
        return out, described, notes

    def _file_motions(self, source, path, clips, sha=None):
        """Return all motions of a file source's file at the clips' rate and length
        (longer ones cut to it, shorter ones left out); a file whose sha256 is not the
        manifest's ``sha`` is refused."""
        from motion.formats import load_motions
        from studyapp.stimuli.clips import file_hash

        if Path(path).is_file() and sha and file_hash(path) != sha:
            raise CommandError(f"--source {source}={path} is not the file the build read (its "
                               f"sha256 is not the manifest's {sha[:12]})")
        frames, fps = clips[0].frames, clips[0].fps
        try:
            loaded = load_motions(path, "auto", fps=fps)
        except (OSError, ValueError) as exc:
            raise CommandError(f"--source {source}={path}: cannot read it: {exc}") from None
        whole = [m if m.frames == frames else m.with_joints(m.joints[:frames])
                 for m in loaded if m.frames >= frames]
        if not whole:
            raise CommandError(f"--source {source}={path}: none of its {len(loaded)} motions "
                               f"lasts the study's {frames} frames")
        return whole

    def _metrics(self, motions, sources, dataset, data_root, classifier, repeats, seed,
                 described=None):
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
        described = described or {s: "the clips the study showed" for s in sources}
        which = "; ".join(f"{s}: {described[s]}" for s in sources)
        details = [
            f"Metrics were measured on each method's motions ({which}) against the real clips "
            f"of dataset {dataset} ({split}); each value is the mean over {repeats} resamples "
            f"(with replacement) of those motions, as `evaluate` reports it. Diversity, "
            f"multimodality and APD count as better the closer they are to the real clips' "
            f"value."
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
                              f"{interval(row['ci_low'], row['ci_high'])}; {values} (metrics on "
                              f"{row['metrics_sample']})")
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
