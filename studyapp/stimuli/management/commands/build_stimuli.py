from pathlib import Path

import yaml
from django.core.management.base import BaseCommand, CommandError

from studyapp.stimuli.build import BuildError, build_stimuli, default_folders
from studyapp.stimuli.config import ConfigError, load_config, resolved_mapping


class Command(BaseCommand):
    help = (
        "Sample, render and register the stimuli of a study config (YAML, see studies/) and "
        "create or update its study; write manifest.json in the build folder. Incremental: "
        "a rerun with the same config changes nothing."
    )

    def add_arguments(self, parser):
        parser.add_argument("config", help="A study config, e.g. studies/a2m_ranking.yaml.")
        parser.add_argument(
            "--set", action="append", default=[], dest="overrides", metavar="FIELD=VALUE",
            help="Override a field (dotted path, YAML value), e.g. --set dataset=demo "
                 "--set train.iters=3 --set sources.1.seed=2. Repeatable.",
        )
        parser.add_argument("--out", help="Build folder (default: <var>/stimuli/<slug>).")
        parser.add_argument("--cache", help="Cache of motions, checkpoints and renders "
                            "(default: <var>/stimuli/cache, shared by every study; the build "
                            "folder with --out).")
        parser.add_argument(
            "--workers", metavar="N|celery",
            help="Render in N processes of this machine, or send the clips to Celery render "
                 "workers on any number of machines with 'celery' (STUDY_CELERY_BROKER; "
                 "`celery -A studyapp worker -Q render` where the cache folder is mounted at "
                 "the same path; docs/PRODUCTION.md). Default: STUDY_RENDER_WORKERS, else "
                 "one process per core.")
        parser.add_argument("--dry-run", action="store_true", help="Check and plan; build nothing.")

    def handle(self, *args, **options):
        try:
            config = load_config(options["config"], options["overrides"])
            for warning in config.warnings:
                self.stderr.write(f"Warning: {warning}")
            folder, cache = default_folders(config, options["out"], options["cache"])
            result = build_stimuli(config, folder, log=self.stdout.write,
                                   dry_run=options["dry_run"], cache=cache,
                                   workers=options["workers"])
        except (ConfigError, BuildError) as exc:
            raise CommandError(str(exc)) from exc
        for warning in result.warnings:
            self.stderr.write(f"Warning: {warning}")
        if not options["dry_run"]:
            # The config as built, beside the manifest: what `bundle` puts in a study's bundle.
            raw = resolved_mapping(options["config"], options["overrides"])
            if raw.get("data_root") and not Path(raw["data_root"]).is_absolute():
                raw["data_root"] = str(Path(options["config"]).resolve().parent / raw["data_root"])
            for source in raw.get("sources") or []:  # file sources readable from the build folder
                if isinstance(source, dict) and source.get("file"):
                    source["file"] = str(config.path(source["file"]))
            (folder / "config.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
            self.stdout.write(
                f"study {result.study.slug}: {len(result.entries)} clips "
                f"({result.rendered} rendered now, sampled now: "
                f"{', '.join(result.sampled) or 'none'}, removed: {result.removed}); "
                f"manifest {result.manifest}"
            )
