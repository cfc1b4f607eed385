"""Print an nginx.conf that serves the app and hands the clips' bytes to nginx."""

from urllib.parse import urlsplit

from django.conf import settings
from django.core.files.storage import default_storage
from django.core.management.base import BaseCommand

from studyapp.participation import proxy_log
from studyapp.stimuli import media


class Command(BaseCommand):
    help = (
        "Print an nginx configuration: nginx on --listen in front of gunicorn on "
        "--upstream, sending clips straight from the files their pages wrote ahead, and "
        "the others from the internal location STUDY_ACCEL_REDIRECT "
        "(the deliveries folder under MEDIA_ROOT) and logging them to --fetch-log for "
        "follow_fetches; with the media in S3, also the location <that>s3/ that fetches a "
        "delivery's own object with the presigned URL the view hands it. make serve writes "
        "it when STUDY_ACCEL_REDIRECT is set."
    )

    def add_arguments(self, parser):
        parser.add_argument("--listen", default="127.0.0.1:8080")
        parser.add_argument("--upstream", default="127.0.0.1:8000")
        parser.add_argument("--run-dir", required=True,
                            help="Folder for nginx's pid file, error log and temporary files.")
        parser.add_argument("--fetch-log", required=True)
        parser.add_argument("--workers", default="auto")
        parser.add_argument("--user", default="",
                            help="User of nginx's workers when started as root (e.g. www-data).")
        parser.add_argument("--real-ip-from", action="append", default=[], metavar="ADDRESS",
                            help="A balancer in front (HAProxy) whose X-Forwarded-For names "
                                 "the participant; repeatable.")
        parser.add_argument("--tls-cert", default="", help="End TLS in nginx: the certificate "
                            "(chain) file; with --tls-key.")
        parser.add_argument("--tls-key", default="")
        parser.add_argument("--no-ahead", dest="ahead", action="store_false",
                            help="Ask the clip view for every clip (as STUDY_DELIVER_AHEAD=0 "
                                 "does, which also stops the pages writing files ahead); "
                                 "default with local media: nginx sends the files the pages "
                                 "wrote straight from the deliveries folder.")
        parser.add_argument("--proto", default="$scheme",
                            help="X-Forwarded-Proto sent to the app (behind a TLS proxy: "
                                 "$http_x_forwarded_proto).")

    def handle(self, *args, listen, upstream, run_dir, fetch_log, workers, proto, user, real_ip_from,
               tls_cert, tls_key, ahead, **options):
        location = settings.STUDY_ACCEL_REDIRECT or "/protected-media/"
        s3_endpoint = ""
        if not media.local_media():  # the host the storage presigns the deliveries for
            url = urlsplit(default_storage.url(media.delivery_name("x", "mp4"), expire=60))
            s3_endpoint = f"{url.scheme}://{url.netloc}"
        self.stdout.write(proxy_log.nginx_config(
            listen=listen, upstream=upstream, media_root=settings.MEDIA_ROOT,
            fetch_log_path=fetch_log, run_dir=run_dir, location=location, workers=workers,
            proto=proto, user=user, real_ip_from=real_ip_from,
            tls_cert=tls_cert, tls_key=tls_key, s3_endpoint=s3_endpoint,
            ahead=ahead and settings.STUDY_DELIVER_AHEAD and not s3_endpoint), ending="")
