from pathlib import Path

from django.conf import settings
from django.core.management import call_command
from django.core.management.base import BaseCommand, CommandError
from django.urls import reverse

from studyapp.survey.demo import DemoPlan, build_demo, demo_studies, ensure_admin
from studyapp.survey.site import DEFAULT_ADDR, AddressError, check_free, record_served, url_of


class Command(BaseCommand):
    help = (
        "Build the embedded demo (train a2m and cond_gru on the synthetic demo data, "
        "sample, render, create one study of every type: ranking, fake or real, rating "
        "with scoring standards, rating with a reference, pairwise) and serve it at "
        "127.0.0.1:8000 (--addr HOST:PORT elsewhere). A second run reuses what was built."
    )

    def add_arguments(self, parser):
        parser.add_argument("--no-serve", action="store_true", help="Build, print links, exit.")
        parser.add_argument("--addr", default=DEFAULT_ADDR,
                            help="Where to serve, HOST:PORT (checked before the build starts).")
        parser.add_argument("--iters", type=int, default=DemoPlan.iters)
        parser.add_argument("--size", type=int, default=DemoPlan.size, help="Clip size in pixels.")
        parser.add_argument("--actions", help="Comma-separated demo actions (default: all 8).")
        parser.add_argument("--clips-per-source", type=int, default=DemoPlan.clips_per_source,
                            help="Clips per source and action.")

    def handle(self, *args, **options):
        if not options["no_serve"]:
            try:  # before a build of minutes, not after it
                check_free(options["addr"])
            except AddressError as exc:
                raise CommandError(str(exc)) from None
        call_command("migrate", interactive=False, verbosity=0)
        root = Path(settings.VAR_DIR) / "demo"
        actions = options["actions"].split(",") if options["actions"] else None
        plan = DemoPlan(iters=options["iters"], size=options["size"], actions=actions,
                        clips_per_source=options["clips_per_source"])
        try:
            build_demo(plan, root, log=self.stdout.write)
        except (ValueError, KeyError, RuntimeError) as exc:
            raise CommandError(f"the demo could not be built: {exc}") from exc
        username, password = ensure_admin(root)
        base = url_of(options["addr"])
        studies = demo_studies(plan)
        width = max(len(study.study_type) for study in studies)
        lines = ["", "Participant links (one study of every type):"]
        lines += [f"  {s.study_type:<{width}}  {s.participant_url(base)}" for s in studies]
        lines += ["Preview as a participant, storing nothing (staff only):"]
        lines += [
            f"  {s.study_type:<{width}}  {base}{reverse('survey:preview', args=[s.slug])}"
            for s in studies
        ]
        lines += [f"Admin: {base}/admin/  (user {username!r}, password {password!r})", ""]
        self.stdout.write(self.style.SUCCESS("\n".join(lines)))
        if not options["no_serve"]:
            record_served(options["addr"])
            call_command("runserver", options["addr"], use_reloader=False)
