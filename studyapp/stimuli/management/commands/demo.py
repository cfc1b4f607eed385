import ipaddress
import secrets
from pathlib import Path

import yaml

from django.conf import settings
from django.contrib.auth import get_user_model
from django.core.management import call_command
from django.core.management.base import BaseCommand, CommandError
from django.core.servers import basehttp
from django.db import transaction
from django.urls import reverse

from studyapp.survey.models import Participant, Study
from studyapp.survey.study_types import get_study_type, list_study_types
from studyapp.survey.site import (
    DEFAULT_ADDR,
    AddressError,
    check_free,
    record_served,
    split_addr,
    url_of,
)
from studyapp.stimuli.build import BuildError, build_stimuli, default_folders
from studyapp.stimuli.config import ConfigError, load_config

DEMO_CONFIGS = Path(settings.BASE_DIR) / "studies" / "demo"
LISTEN_BACKLOG = 1024  # connections the demo server's socket queues (Django's default: 10)


def is_loopback(host: str) -> bool:
    """Return whether ``host`` (a name or an address) is this machine's loopback only."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # another name: it may resolve to any interface


def demo_configs(folder: Path = DEMO_CONFIGS) -> list[tuple[Path, list[str]]]:
    """Return the demo's study configs as ``(path, overrides)``: every YAML file of the
    folder but ``_*`` ones, then, for each registered study type that none of them
    builds, ``_common.yaml`` with the type's key, slug and label, so a new type is in the
    demo without a file of its own (give it one to set its options)."""
    paths = sorted(p for p in folder.glob("*.yaml") if not p.name.startswith("_"))
    configs = [(path, []) for path in paths]
    common = folder / "_common.yaml"
    if not common.is_file():
        return configs
    named = {((yaml.safe_load(path.read_text()) or {}).get("study") or {}).get("type")
             for path in paths}
    for key in list_study_types():
        if key not in named:
            configs.append((common, [f"slug=demo-{key.replace('_', '-')}",
                                     f"title={get_study_type(key).label}",
                                     f"study.type={key}"]))
    return configs


def ensure_admin(root: Path) -> tuple[str, str]:
    """Create the demo's admin account once; return (username, password)."""
    secret = root / "admin-password.txt"
    username = "admin"
    if not secret.is_file():
        root.mkdir(parents=True, exist_ok=True)
        secret.write_text(secrets.token_urlsafe(9))
        secret.chmod(0o600)
    password = secret.read_text().strip()
    users = get_user_model().objects
    user = users.filter(username=username).first()
    if user is None:
        users.create_superuser(username, "", password)
    elif not user.check_password(password):
        user.set_password(password)
        user.save()
    return username, password


class Command(BaseCommand):
    help = (
        "Build the demo studies (studies/demo/*.yaml, one study of every type, through the "
        "same build as build_stimuli: synthetic demo data, two methods whose tiny "
        "checkpoints ship with the code) and serve them at 127.0.0.1:8000 (--addr "
        "HOST:PORT elsewhere; on anything but loopback with DEBUG off). A second run reuses "
        "what was built."
    )

    def add_arguments(self, parser):
        parser.add_argument("--no-serve", action="store_true", help="Build, print links, exit.")
        parser.add_argument("--addr", default=DEFAULT_ADDR,
                            help="Where to serve, HOST:PORT (checked before the build starts).")
        parser.add_argument("--configs", default=str(DEMO_CONFIGS),
                            help="Folder of the demo's study configs.")
        parser.add_argument("--only", help="Comma-separated study types to build (default: all).")
        parser.add_argument("--set", action="append", default=[], dest="overrides",
                            metavar="FIELD=VALUE", help="Override a field of every config "
                            "(as build_stimuli --set), e.g. --set render.size=240.")
        parser.add_argument("--actions", help="Comma-separated demo actions (default: all 8).")
        parser.add_argument("--clips-per-source", type=int, help="Clips per source and action.")
        parser.add_argument("--size", type=int, help="Clip size in pixels.")
        parser.add_argument("--reset", action="store_true",
                            help="Delete the demo studies and their answers first.")

    def overrides(self, options) -> list[str]:
        out = list(options["overrides"])
        if options["actions"]:
            out.append(f"actions=[{options['actions']}]")
        if options["clips_per_source"]:
            out.append(f"clips_per_source={options['clips_per_source']}")
        if options["size"]:
            out.append(f"render.size={options['size']}")
        return out

    def handle(self, *args, **options):
        if not options["no_serve"]:
            try:  # before a build of minutes, not after it
                check_free(options["addr"])
            except AddressError as exc:
                raise CommandError(str(exc)) from None
        call_command("migrate", interactive=False, verbosity=0)
        paths = demo_configs(Path(options["configs"]))
        if not paths:
            raise CommandError(f"no study configs (*.yaml) in {options['configs']}")
        only = set(options["only"].split(",")) if options["only"] else None
        try:
            configs = [load_config(path, [*fixed, *self.overrides(options)])
                       for path, fixed in paths]
        except ConfigError as exc:
            raise CommandError(f"the demo could not be built: {exc}") from None
        configs = [c for c in configs if only is None or c.study_type in only]
        if options["reset"]:
            slugs = [c.slug for c in configs]
            with transaction.atomic():
                Participant.objects.filter(study__slug__in=slugs).delete()
                Study.objects.filter(slug__in=slugs).delete()
        studies = []
        for number, config in enumerate(configs, 1):
            self.stdout.write(f"demo: study {number} of {len(configs)}: {config.slug} "
                              f"({config.study_type})")
            folder, cache = default_folders(config)
            try:
                result = build_stimuli(config, folder, log=self.stdout.write, cache=cache)
            except (ConfigError, BuildError, ValueError, RuntimeError) as exc:
                raise CommandError(f"the demo study {config.slug} could not be built: {exc}; "
                                   f"`manage.py demo --reset` starts it afresh") from exc
            studies.append(result.study)
            state = "unchanged" if result.unchanged else "registered"
            self.stdout.write(f"demo: {config.slug}: {len(result.entries)} clips, "
                              f"{result.rendered} rendered now, {state}")
        username, password = ensure_admin(Path(settings.VAR_DIR) / "demo")
        base = url_of(options["addr"])
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
            self.serve(options["addr"])

    def serve(self, addr: str) -> None:
        """Serve at ``addr``: with Django's debug pages (settings, paths, tracebacks) on
        loopback only; listening on anything else, with ``DEBUG`` off."""
        host, _ = split_addr(addr)
        if not is_loopback(host):
            settings.DEBUG = False
            self.stdout.write(
                f"demo: listening on {host}, so DEBUG is off (no debug pages with settings and "
                f"paths); other machines reach it by the names in DJANGO_ALLOWED_HOSTS (now "
                f"{','.join(settings.ALLOWED_HOSTS)})")
        # Django's development server listens with a queue of 10 connections: with dozens
        # of participants (or simulate_participants' bots) at once the rest are dropped and
        # retried 1, 2, 4, 8... s later, long enough for a request to time out.
        basehttp.WSGIServer.request_queue_size = LISTEN_BACKLOG
        # DEBUG off: runserver serves the static files only when asked (insecure_serving).
        call_command("runserver", addr, use_reloader=False, insecure_serving=not settings.DEBUG)
