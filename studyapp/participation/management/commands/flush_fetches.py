"""Write every clip-fetch witness (Redis, or this machine's spool) into the database."""

import time

from django.core.management.base import BaseCommand

from studyapp.participation import fetch_log


class Command(BaseCommand):
    help = (
        "Fold the records of clips sent to their last byte that are still waiting in Redis "
        "(STUDY_FETCH_LOG_URL / STUDY_CACHE_URL) or in this machine's spool "
        "(STUDY_FETCH_SPOOL) into the trial items (fetched, fetched_at), in one statement "
        "per batch. Web workers do this every STUDY_FETCH_FLUSH_S seconds and on every "
        "answer; run it by hand before an export of unfinished sessions, or with --every "
        "as a sidecar when the workers' own flushing is off (STUDY_FETCH_FLUSH_S=0)."
    )

    def add_arguments(self, parser):
        parser.add_argument("--every", type=float, default=0, metavar="SECONDS",
                            help="Flush again every SECONDS (0: once).")

    def handle(self, *args, every, **options):
        while True:
            changed = fetch_log.flush()
            self.stdout.write(f"{changed} trial items updated from fetch witnesses")
            if every <= 0:
                return
            time.sleep(every)
