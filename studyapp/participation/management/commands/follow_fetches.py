"""Read nginx's access log of the clips it sent into fetch witnesses (make serve runs it)."""

from django.core.management.base import BaseCommand

from studyapp.participation import proxy_log


class Command(BaseCommand):
    help = (
        "With STUDY_ACCEL_REDIRECT (nginx sends the clips' bytes): read the access log of "
        "nginx's internal clip location as nginx writes it and record every response sent "
        "whole as a fetch witness (Redis, or this machine's spool), where answers find it. "
        "Run one beside each nginx; it keeps its place in <log>.offset."
    )

    def add_arguments(self, parser):
        parser.add_argument("--log", required=True, help="The access log nginx_config named.")
        parser.add_argument("--once", action="store_true",
                            help="Read what is there and stop (default: follow the log).")
        parser.add_argument("--poll", type=float, default=0.05, metavar="SECONDS")

    def handle(self, *args, log, once, poll, **options):
        if once:
            count = proxy_log.read_new(log)
            self.stdout.write(f"{count} fetch witnesses recorded from {log}")
            return
        proxy_log.follow(log, poll=poll)
