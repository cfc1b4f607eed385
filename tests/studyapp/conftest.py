"""Fixtures of the survey app: tiny playable clips, studies of every type, a bot, a browser."""

import hashlib
import os
import re
from pathlib import Path

import numpy as np
import pytest

# Playwright's sync API runs an event loop in this thread; Django refuses ORM calls
# from a thread with a running loop unless told it is safe here.
os.environ["DJANGO_ALLOW_ASYNC_UNSAFE"] = "true"

ACTIONS = ("walk", "wave")
SOURCES = ("real", "a2m", "cond_gru")
CATCH_SOURCE = "broken"
EXAMPLE_SOURCE = "standard_example"
FPS = 25
FRAMES = 10
SIZE = 64
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
]


def write_clip(path: Path, colour, frames=FRAMES, size=SIZE) -> None:
    """Write an H.264 mp4 of a bar sweeping over a solid colour."""
    import imageio_ffmpeg

    writer = imageio_ffmpeg.write_frames(
        str(path),
        (size, size),
        fps=FPS,
        codec="libx264",
        pix_fmt_out="yuv420p",
        output_params=["-movflags", "+faststart", "-map_metadata", "-1"],
        macro_block_size=16,
        ffmpeg_log_level="error",
    )
    writer.send(None)
    for t in range(frames):
        frame = np.empty((size, size, 3), np.uint8)
        frame[:] = colour
        row = (t * size) // frames
        frame[row : row + size // 8] = 255 - np.asarray(colour, np.uint8)
        writer.send(frame.tobytes())
    writer.close()


def write_poster(path: Path, colour, size=SIZE) -> None:
    import imageio.v3 as iio

    iio.imwrite(path, np.full((size, size, 3), colour, np.uint8))


@pytest.fixture(scope="session")
def django_db_modify_db_settings(django_db_modify_db_settings_parallel_suffix, tmp_path_factory):
    """Keep SQLite's test database in a file rather than shared memory.

    Threads (concurrent participants, the live server) then wait for each other's write
    lock as separate processes do; a shared-cache memory database fails at once with
    "database table is locked". PostgreSQL is left as configured.
    """
    from django.db import connections

    db = connections["default"].settings_dict
    if db["ENGINE"].endswith("sqlite3") and not db["TEST"].get("NAME"):
        db["TEST"]["NAME"] = str(tmp_path_factory.mktemp("db") / "test.sqlite3")
        db["OPTIONS"] = {
            **db.get("OPTIONS", {}),
            "timeout": 30,
            "transaction_mode": "IMMEDIATE",
            "init_command": "PRAGMA synchronous=OFF; PRAGMA journal_mode=WAL;",
        }


@pytest.fixture(autouse=True)
def _quick_watch(settings):
    """Unit tests fetch every clip but need not sit through it; the tests of the watch
    rule itself set STUDY_WATCH_TIME_FACTOR back to 1."""
    settings.STUDY_WATCH_TIME_FACTOR = 0.0


@pytest.fixture(autouse=True)
def _fresh_rate_limits():
    """Start every test with no entries counted: the per-process cache outlives a test,
    and tests reuse study slugs (the limit per study and address would carry over)."""
    from django.core.cache import cache

    cache.clear()


@pytest.fixture(scope="session")
def clips(tmp_path_factory) -> list:
    """Return 2 actions x 3 sources of real, distinct, playable clips (written once)."""
    from studyapp.stimuli.clips import Clip

    root = tmp_path_factory.mktemp("clips")
    rng = np.random.default_rng(0)
    out = []
    for action in ACTIONS:
        for source in SOURCES:
            colour = tuple(int(c) for c in rng.integers(30, 225, size=3))
            name = f"{action}-{source}"
            write_clip(root / f"{name}.mp4", colour)
            write_poster(root / f"{name}.png", colour)
            out.append(Clip(action, source, root / f"{name}.mp4", FRAMES / FPS,
                            motion_hash=name, poster=root / f"{name}.png"))
    return out


@pytest.fixture(scope="session")
def extra_clips(tmp_path_factory) -> list:
    """Return, per action, clips of every extra role a study type may ask for: a
    reference, five scoring-standard examples, a catch clip and a low anchor; and five
    practice clips of the first action (as many as a MUSHRA trial of 3 sources shows)."""
    from studyapp.stimuli.clips import Clip

    root = tmp_path_factory.mktemp("extra-clips")
    rng = np.random.default_rng(1)
    out = []
    roles = [("reference", "real", "reference", None)]
    roles += [(f"score{k}", EXAMPLE_SOURCE, "example", k) for k in range(1, 6)]
    roles += [("catch", CATCH_SOURCE, "catch", None), ("anchor", "anchor", "anchor", None)]
    practice = [(f"practice{k}", "practice_clip", "practice", None) for k in range(5)]
    for action in ACTIONS:
        for name, source, role, score in roles + (practice if action == ACTIONS[0] else []):
            colour = tuple(int(c) for c in rng.integers(30, 225, size=3))
            path = root / f"{action}-{name}.mp4"
            write_clip(path, colour)
            write_poster(path.with_suffix(".png"), colour)
            out.append(Clip(action, source, path, FRAMES / FPS, motion_hash=f"{action}-{name}",
                            poster=path.with_suffix(".png"), role=role, score=score))
    return out


def make_study(study_type, clips, extra_clips=(), slug=None, catch=False, **fields):
    """Create an open study of any type from the test clips, with what the type needs.

    The study type says which extra clips it needs (``stimulus_roles``: a reference,
    scoring-standard examples, anchors, practice clips with ``practice=True``); ``catch``
    adds the broken clips (and one catch trial per participant unless ``catch_trials``
    says otherwise). Fields that are the type's own options go into ``Study.options``.
    The type finishes the study as a build would (``after_register``).
    """
    from studyapp.survey.models import Study
    from studyapp.stimuli.clips import register_clips
    from studyapp.survey.study_types import get_study_type

    kind = get_study_type(study_type)
    fields.setdefault("data_note", "The motions in this study are synthetic demo data.")
    for name, value in kind.defaults(len(SOURCES)).items():
        fields.setdefault(name, value)
    if catch:
        fields.setdefault("catch_trials", 1)
    options = {name: fields.pop(name) for name in list(fields) if name in kind.options}
    slug = slug or f"study-{study_type.replace('_', '-')}"
    study = Study.objects.create_study(study_type, slug, "Movement study", options=options,
                                       **fields)
    roles = kind.stimulus_roles({**fields, "catch_trials": fields.get("catch_trials", 0)})
    wanted = list(clips) + [clip for clip in extra_clips if clip.role in roles]
    stimuli = register_clips(study, wanted)
    kind.after_register(study, wanted, stimuli)
    return study


@pytest.fixture
def media_root(settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    return settings.MEDIA_ROOT


def make_ranking_study(clips, slug="motion-study", **fields):
    return make_study("ranking", clips, slug=slug, **fields)


@pytest.fixture
def ranking_study(db, media_root, clips):
    """Return an open ranking study: 2 actions x 3 sources, 3 clips per trial."""
    return make_ranking_study(clips, completion_url="https://platform.example/complete?cc=OK")


def make_stimuli(study, actions=ACTIONS, sources=SOURCES, per_cell=1):
    """Add file-less stimuli to a study, for tests of assignment alone."""
    from studyapp.survey.models import Stimulus

    return [
        Stimulus.objects.create(
            study=study,
            action=action,
            source=source,
            video=f"stimuli/missing-{action}-{source}-{k}.mp4",
            duration=1.0,
            video_hash=hashlib.sha256(f"{study.pk}/{action}/{source}/{k}".encode()).hexdigest(),
        )
        for action in actions
        for source in sources
        for k in range(per_cell)
    ]


class Bot:
    """Play a study through the same pages a person uses (as oTree's bots do)."""

    def __init__(self, client, study):
        self.client = client
        self.study = study

    def url(self, name=""):
        return f"/s/{self.study.slug}/{name + '/' if name else ''}"

    def enter(self, **params):
        return self.client.get(self.url(), params, follow=True)

    def consent(self, agree=True, **data):
        data = ({"agree": "1"} if agree else {}) | data
        return self.client.post(self.url("consent"), data, follow=True)

    def start(self):
        return self.client.post(self.url("instructions"), follow=True)

    def join(self, **params):
        self.enter(**params)
        self.consent()
        return self.start()

    def participant(self):
        from studyapp.survey.models import Participant

        from studyapp.participation.flow import cookie_name, token_from_cookie

        token = token_from_cookie(self.client.cookies[cookie_name(self.study)].value)
        return Participant.objects.get(token=token)

    def trial_page(self, watch=True):
        """Open the current trial page and, as a browser does, fetch its clips whole."""
        response = self.client.get(self.url("trial"))
        if watch:
            self.watch()
        return response

    def watch(self, trial=None):
        """Fetch every required clip of ``trial`` (default: the current one) to its end."""
        trial = trial or self.participant().current_trial()
        for item in trial.items.filter(required=True):
            response = self.client.get(item.clip_url())
            assert response.status_code == 200, response.status_code
            b"".join(response.streaming_content)

    def answer_data(self, trial, plays=1, **answers):
        """Return a valid POST for ``trial`` of the study's type: ``answers`` by the type's
        own keywords (see ``StudyType.answer_fields``), defaults where absent."""
        from studyapp.survey.study_types import get_study_type

        items = list(trial.items.select_related("stimulus").order_by("position"))
        data = {"trial": str(trial.pk)}
        data.update({f"plays_{item.token}": str(plays) for item in items})
        data.update(get_study_type(self.study.study_type).answer_fields(items, **answers))
        return data

    def answer(self, data, follow=False):
        return self.client.post(self.url("trial"), data, follow=follow)

    def finish(self, **answers):
        """Answer every remaining trial alike (the screen order); return the last response."""
        response = None
        while (trial := self.participant().current_trial()) is not None:
            self.trial_page()
            response = self.answer(self.answer_data(trial, **answers), follow=True)
        return response


@pytest.fixture
def make_bot(db):
    """Return a factory of bots, each with its own browser session."""
    from django.test import Client

    return lambda study: Bot(Client(), study)


@pytest.fixture(scope="session")
def browser():
    """Start Debian's Chromium once for the whole session."""
    if not Path(CHROMIUM).exists():
        if os.environ.get("STUDY_REQUIRE_BROWSER"):
            pytest.fail(f"{CHROMIUM} not installed, and STUDY_REQUIRE_BROWSER is set (CI)")
        pytest.skip(f"{CHROMIUM} not installed (make setup installs it when run as root)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport={"width": 1280, "height": 860})
    page = context.new_page()
    page.set_default_timeout(15_000)
    yield page
    context.close()


@pytest.fixture
def phone_page(browser):
    context = browser.new_context(
        viewport={"width": 390, "height": 844},
        device_scale_factor=2,
        is_mobile=True,
        has_touch=True,
    )
    page = context.new_page()
    page.set_default_timeout(15_000)
    yield page
    context.close()


def words(text: str, label: str) -> list[str]:
    """Return the places ``label`` occurs in ``text`` as a word of its own."""
    pattern = rf"(?<![A-Za-z0-9]){re.escape(label)}(?![A-Za-z0-9])"
    return [text[max(0, m.start() - 40) : m.end() + 40] for m in re.finditer(pattern, text, re.I)]


def shown_item(stimulus):
    """Return a trial item showing ``stimulus`` to a new participant (its clip URL is what
    a participant would fetch)."""
    from studyapp.survey.models import Participant, Trial, TrialItem

    participant = Participant.objects.create(study=stimulus.study, seed=1)
    trial = Trial.objects.create(participant=participant, index=0, action=stimulus.action)
    return TrialItem.objects.create(trial=trial, stimulus=stimulus, position=0)


def require_service(available: bool, what: str) -> None:
    """Skip a test when a service it needs (nginx, HAProxy, Redis, PostgreSQL) is missing;
    fail instead when ``STUDY_REQUIRE_SERVICES`` is set (CI has them all)."""
    if available:
        return
    if os.environ.get("STUDY_REQUIRE_SERVICES"):
        pytest.fail(f"{what} is not available, and STUDY_REQUIRE_SERVICES is set (CI)")
    pytest.skip(f"{what} is not available")
