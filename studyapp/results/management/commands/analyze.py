import argparse
from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from analysis.formatting import interval, number
from analysis.report import write_report
from analysis.study import AnalysisConfig, analyse_all
from analysis.tables import AnalysisError, read_responses, write_responses
from studyapp.participation.adaptive import settings as adaptive_settings
from studyapp.results import export
from studyapp.results.audit import AuditUnavailable, audit_study, view_fetcher
from studyapp.results.export import get_study, responses_frame
from studyapp.results.analysis_page import note_report


# The study's design the methods paragraph states (Study fields).
STUDY_OPTIONS = ("practice", "catch_trials", "instructed_checks", "repeat_trials", "design",
                 "adaptive", "stop_when", "stopped")


class Command(BaseCommand):
    help = (
        "Analyse a study's answers for its study type: statistics with confidence intervals, "
        "tests, agreement and exclusions, written as report.html, summary.json, tables "
        "(CSV, Markdown, LaTeX) and figures (PNG, SVG)."
    )

    def add_arguments(self, parser):
        source = parser.add_mutually_exclusive_group(required=True)
        source.add_argument("--study", metavar="SLUG", help="Analyse this study's stored answers.")
        source.add_argument("--responses", metavar="FILE",
                            help="Analyse an exported response table (.csv or .parquet) instead.")
        parser.add_argument("--out", required=True, metavar="DIR")
        parser.add_argument("--completed-only", action="store_true",
                            help="Leave out participants who did not finish the study.")
        parser.add_argument("--no-exclusions", action="store_true",
                            help="Keep participants who failed catch trials and too-fast answers "
                                 "(the report still counts them).")
        parser.add_argument("--min-time-factor", type=float, default=1.0, metavar="F",
                            help="Exclude trials answered in less than F x the clip length (default 1).")
        parser.add_argument("--max-failed-catch", type=int, default=None, metavar="N",
                            help="Exclude participants who failed more than N catch trials "
                                 "(default: the study's own max_failed_catch, else 0).")
        parser.add_argument("--max-failed-repeats", type=int, default=None, metavar="N",
                            help="Also exclude participants who answered more than N repeated "
                                 "trials differently (default: counted, not applied).")
        parser.add_argument("--bootstrap", type=int, default=1000, metavar="N",
                            help="Bootstrap resamples of participants, and as many of clips, "
                                 "for every interval and test (default 1000; 0 = none).")
        parser.add_argument("--fixed-clips", action="store_true",
                            help="Take the clips shown as the whole population of interest: "
                                 "intervals over participants only, which hold for these clips "
                                 "and say nothing about other clips of the same sources.")
        parser.add_argument("--mixed-models", action="store_true",
                            help="Also fit mixed models with crossed random effects for "
                                 "participants and clips (scores, fake or real, and worths as "
                                 "Bradley-Terry; seconds to a minute per fit) beside the "
                                 "bootstrap.")
        parser.add_argument("--seed", type=int, default=0, help="Seed of the bootstrap.")
        parser.add_argument("--no-audit", action="store_true",
                            help="Skip the blindness audit of the study's clips (the deep "
                                 "audit of audit_blindness, run in this process).")
        parser.add_argument("--real-source", default="real", metavar="NAME",
                            help="The source holding real clips (for a fake-or-real study; default 'real').")
        parser.add_argument("--manifest", metavar="FILE",
                            help="The study's build manifest: its method checkpoints (hash, "
                                 "budget, training seed) and their objective metrics become a "
                                 "table of the report (default: the build folder's, "
                                 "<var>/stimuli/<slug>/manifest.json, when there).")
        # Kept for old scripts: SVGs are always written now.
        parser.add_argument("--svg", action="store_true", help=argparse.SUPPRESS)

    def handle(self, *args, study, responses, out, **options):
        participants = None
        type_options, study_options = {}, {}
        if responses:
            try:
                table = read_responses(responses)
            except (AnalysisError, OSError, ValueError) as error:
                raise CommandError(f"Cannot read {responses}: {error}") from None
            name = Path(responses).name
            if options["max_failed_catch"] is None:
                options["max_failed_catch"] = 0
        else:
            record = get_study(study)
            table = responses_frame(record)
            participants = _participants(record)
            name = record.slug
            # Every option of the type, defaults included: the report describes what ran.
            type_options = {name: record.option(name) for name in record.kind.options}
            study_options = {name: getattr(record, name) for name in STUDY_OPTIONS}
            if record.design == "adaptive":  # the settings that ran, defaults included
                study_options["adaptive"] = {**adaptive_settings(record), **(
                    {"batch": record.sampling["batch"]} if "batch" in (record.sampling or {}) else {})}
            if options["max_failed_catch"] is None:
                options["max_failed_catch"] = record.max_failed_catch  # as its outcomes
            if table.empty:
                raise CommandError(f"Study {name} has no answers yet; nothing to analyse.")
        out = Path(out)
        try:
            config = AnalysisConfig(
                exclusions=not options["no_exclusions"], min_time_factor=options["min_time_factor"],
                max_failed_catch=options["max_failed_catch"],
                max_failed_repeats=options["max_failed_repeats"], completed_only=options["completed_only"],
                bootstrap=options["bootstrap"], seed=options["seed"], real_source=options["real_source"],
                random_clips=not options["fixed_clips"], mixed_models=options["mixed_models"],
                type_options=type_options, study_options=study_options,
            )
            results = analyse_all(table, config, participants=participants)
            _add_stimulus_sources(results, options["manifest"], None if responses else record)
            if not responses and not options["no_audit"]:
                try:
                    blindness = audit_study(record, view_fetcher(), "deep")
                except AuditUnavailable as error:
                    for result in results:
                        result.notes.append(f"the blindness audit did not run: {error}")
                else:
                    for result in results:
                        result.blindness = blindness
            out.mkdir(parents=True, exist_ok=True)
            if not responses:
                write_responses(table, out / "responses.csv")
            reports = []
            for result in results:
                # One question: the report is the folder's; several: one folder each.
                folder = out if len(results) == 1 else out / result.criterion
                written = write_report(result, folder, title=_title(study, result))
                reports.append((result, written, folder))
            if len(results) > 1:
                _write_index(out, name, results)
            if not responses:
                note_report(record, out)  # the admin's Results page shows the latest
        except (AnalysisError, OSError, ValueError) as error:
            raise CommandError(f"Cannot analyse {name}: {error}") from None
        for result, written, folder in reports:
            self._print(name, result, written, folder)

    def _print(self, name, result, written, out):
        counts, summary = result.counts, result.summary()
        removed = counts["participants_before"] - counts["participants"]
        asked = f", criterion {result.criterion}" if result.criterion else ""
        self.stdout.write(
            f"Study {name} ({result.study_type}{asked}): {counts['participants']} participants, "
            f"{counts['judgements']} judgements"
            + (f" ({removed} participants excluded or without answers)." if removed else ".")
        )
        self.stdout.write(f"Sources by {summary['measure']} (best first):")
        sources = result.analysis.sources
        for place, (source, row) in enumerate(sources.iterrows(), start=1):
            extra = f", mean rank {row['mean_rank']:.2f}" if "mean_rank" in sources.columns else ""
            self.stdout.write(
                f"  {place}. {source}: {number(row['score'])} {interval(row['ci_low'], row['ci_high'])}"
                f"{extra}, n={int(row['n_judgements'])}"
            )
        for note in result.notes:
            self.stderr.write(self.style.WARNING(f"Note: {note}."))
        for label, part in (result.blindness or {}).items():
            if not part["passed"]:
                self.stderr.write(self.style.WARNING(
                    f"Blindness audit: {label} can be told apart from the served files: "
                    f"{part['says']}."))
        tables = sum(1 for path in written if path.suffix == ".csv")
        figures = sum(1 for path in written if path.suffix == ".png")
        headline = sum(1 for path in written if path.name.startswith("headline_"))
        self.stdout.write(f"Wrote report.html, summary.json, {tables} tables (CSV, Markdown, LaTeX) "
                          f"and {figures} figures (PNG, SVG), supplement.html and .pdf (one "
                          f"page) and {headline} headline LaTeX tables to {out}.")


def _add_stimulus_sources(results, manifest, study) -> None:
    """Add the build manifest's table of method checkpoints and their metrics to each result,
    and a sentence per method source to its methods paragraph."""
    import json

    from django.conf import settings

    from analysis.registry import Table
    from studyapp.stimuli.sources import sources_sentences, sources_table

    if manifest is None and study is not None:
        found = Path(settings.VAR_DIR) / "stimuli" / study.slug / "manifest.json"
        manifest = found if found.is_file() else None
    if manifest is None:
        return
    try:
        built = json.loads(Path(manifest).read_text())
    except (OSError, ValueError) as error:
        raise CommandError(f"Cannot read the manifest {manifest}: {error}; give the build's "
                           f"manifest.json with --manifest") from None
    frame = sources_table(built)
    if frame is None:
        return
    about = built.get("metrics") or {}
    classifier = about.get("classifier")
    title = (f"Stimulus sources: each method checkpoint (sha256 prefix), its training budget and "
             f"seed, and its objective metrics at build time ({about.get('n')} motions per action, "
             f"{about.get('repeats')} repeats, MMD protocol {about.get('mmd_protocol')}"
             + (f"; classifier held-out accuracy {classifier['test_accuracy']:.3f}" if classifier
                and classifier.get("test_accuracy") is not None else "") + ")")
    sentences = sources_sentences(built)
    for result in results:
        result.appendix.append(Table("stimulus_sources", title, frame))
        result.sources_text = list(sentences)
        result.notes.extend(about.get("notes") or [])


def _participants(study):
    """Return the per-participant table (demographics) when the export provides one."""
    frame = getattr(export, "participants_frame", None)
    return frame(study) if frame is not None else None


def _title(slug, result):
    asked = f" ({result.criterion})" if result.criterion else ""
    return f"{slug or result.study or 'Study'}: {result.study_type.replace('_', ' ')}{asked}"


def _write_index(out: Path, name: str, results) -> None:
    """Write ``report.html`` linking the report of each criterion of a study."""
    from html import escape

    links = "".join(
        f'<li><a href="{escape(r.criterion)}/report.html">{escape(r.criterion)}</a>: '
        f"{r.counts['participants']} participants, {r.counts['judgements']} judgements</li>"
        for r in results)
    (out / "report.html").write_text(
        f"<!doctype html><meta charset=utf-8><title>{escape(name)}</title>"
        f"<h1>{escape(name)}: one report per question</h1><ul>{links}</ul>\n")
