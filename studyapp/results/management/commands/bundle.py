from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from studyapp.results.bundle import BundleError, write_bundle
from studyapp.results.export import get_study
from studyapp.results.study_motions import default_paths


class Command(BaseCommand):
    help = (
        "Write a study's bundle (.zip): its config as built, the build manifest, every "
        "stimulus motion as interchange .npz and BVH, clip hashes, the exported responses, "
        "the analysis (and the command that re-runs it), package versions and the commit; "
        "rebuild.yaml in it rebuilds the clips with build_stimuli."
    )

    def add_arguments(self, parser):
        parser.add_argument("--study", required=True, metavar="SLUG")
        parser.add_argument("--out", required=True, metavar="F.zip")
        parser.add_argument("--config", metavar="CONFIG",
                            help="The YAML that built the study (default: the copy "
                                 "build_stimuli keeps in the build folder).")
        parser.add_argument("--manifest", metavar="FILE",
                            help="The build's manifest.json (default: <var>/stimuli/<slug>/).")
        parser.add_argument("--cache", metavar="DIR",
                            help="The build's cache (default: the manifest's folder, then "
                                 "<var>/stimuli/cache).")

    def handle(self, *args, study, out, config=None, manifest=None, cache=None, **options):
        record = get_study(study)
        default_manifest, default_cache = default_paths(record.slug)
        manifest = Path(manifest) if manifest else default_manifest
        folders = [Path(cache)] if cache else list(dict.fromkeys([manifest.parent,
                                                                  default_cache]))
        try:
            write_bundle(record, Path(out), manifest.parent, folders, config,
                         log=self.stdout.write)
        except BundleError as exc:
            raise CommandError(str(exc)) from None
