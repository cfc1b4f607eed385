"""List the datasets found: ``manage.py datasets [NAME ...] [--json] [--data-root DIR]``."""

import json
from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from motion.datasets import DatasetError, get_dataset, list_datasets


class Command(BaseCommand):
    help = (
        "List the registered datasets with their skeleton, actions and number of clips at "
        "the default clip length. A dataset whose data is not found is listed with the "
        'reason; with --json it appears as {"error": reason} instead of '
        '{"skeleton", "actions", "clips"}.'
    )
    requires_system_checks = []  # reads data files only: no database, models or URLs

    def add_arguments(self, parser):
        parser.add_argument("names", nargs="*", metavar="NAME",
                            help=f"datasets to list (default: all of {', '.join(list_datasets())})")
        parser.add_argument("--json", action="store_true",
                            help="print {name: {skeleton, actions, clips}} (or {error}) as JSON")
        parser.add_argument("--data-root", type=Path, metavar="DIR",
                            help="read the listed datasets from DIR instead of their default "
                            "folder (name the dataset, e.g. 'datasets humanact12 --data-root DIR')")

    def handle(self, *args, **options):
        names = options["names"] or list_datasets()
        unknown = [name for name in names if name not in list_datasets()]
        if unknown:
            raise CommandError(f"unknown dataset {', '.join(unknown)}; "
                               f"choose from {', '.join(list_datasets())}")
        root = options["data_root"]
        if root is not None and not root.is_dir():
            raise CommandError(f"--data-root {root} is not a folder")
        datasets = {name: get_dataset(name, root) for name in names}
        found = {}
        for name, dataset in datasets.items():
            try:
                found[name] = {"skeleton": dataset.skeleton, "actions": dataset.actions(),
                               "clips": dataset.count_clips()}
            except DatasetError as exc:
                found[name] = {"error": str(exc)}
        if options["json"]:
            self.stdout.write(json.dumps(found, indent=2))
            return
        for name, info in found.items():
            if "error" in info:
                self.stdout.write(f"{name}: not available: {info['error']}")
                continue
            dataset = datasets[name]
            origin = "synthetic, built in" if dataset.synthetic else f"from {dataset.data_root}"
            self.stdout.write(
                f"{name}: skeleton {info['skeleton']}, {info['clips']} clips of "
                f"{dataset.clip_frames} frames at {dataset.clip_fps:g} fps ({origin})\n"
                f"  {len(info['actions'])} actions: {', '.join(info['actions'])}"
            )
