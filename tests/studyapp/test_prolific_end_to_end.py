"""Prolific end to end: `prolific create` makes the study on the local server that follows
Prolific's published API, simulated participants open it on Prolific and take it through
our real pages from the link Prolific gives them (bt, inattentive and declining bots),
come back to Prolific through the redirect our last page sent them to, and `prolific
review` approves and returns exactly as our exclusions say. A failed participant who
comes back under a made-up id gets the completed code, but review still goes by the
outcome of their real id and flags the made-up one."""

import random
import secrets
from io import StringIO

import pytest
from django.core.management import call_command

from studyapp.participation import bots
from studyapp.survey.models import Participant
from studyapp.crowd.platforms.prolific import prolific_time_limit
from tests.studyapp.conftest import SOURCES, make_study
from tests.studyapp.prolific_fake import COMPLETE_URL, FakeProlific

pytestmark = [pytest.mark.slow, pytest.mark.django_db(transaction=True)]

TOKEN = "test-token"
RUNS = {"bt": 2, "inattentive": 1, "decline": 1}  # policy: bots


def run(*args) -> str:
    out = StringIO()
    call_command(*args, stdout=out, stderr=StringIO())
    return out.getvalue()


def take(study, policy, url, seed):
    """A bot of ``policy`` with its own cookies takes the study from ``url``."""
    rng = random.Random(seed)
    bot = bots.Bot(study, bots.POLICIES.get(policy)(rng, {}, SOURCES), rng, pace=0)
    return bot, bot.run(url)


def test_prolific_study_from_creation_to_review(transactional_db, media_root, clips, extra_clips,
                                                live_server, monkeypatch):
    # One catch trial and one instructed check: failing both is a failed attention check.
    study = make_study("ranking", clips, extra_clips, slug="prolific-e2e", catch=True,
                       instructed_checks=1, trials_per_participant=2, max_participants=10)
    with FakeProlific(token=TOKEN) as fake:
        monkeypatch.setenv("PROLIFIC_TOKEN", TOKEN)
        monkeypatch.setenv("PROLIFIC_API_URL", fake.url)
        run("prolific", "create", "--study", study.slug, "--base-url", live_server.url,
            "--review-completed")
        run("prolific", "publish", "--study", study.slug)
        study.refresh_from_db()
        remote = fake.studies[study.crowd["prolific_study_id"]]
        assert remote["external_study_url"].startswith(f"{live_server.url}/s/{study.slug}/?")
        # Prolific's default for the study's estimated minutes: at least its minimum.
        limit = prolific_time_limit(study.minutes())
        assert remote["maximum_allowed_time"] == study.crowd["time_limit_minutes"] == limit

        came_back, seed = {}, 0
        for policy, n in RUNS.items():
            for _ in range(n):
                seed += 1
                pid = secrets.token_hex(12)
                _, url = fake.start(remote["id"], pid)  # they open the study on Prolific
                bot, outcome = take(study, policy, url, seed)
                assert outcome.exit_url == f"{COMPLETE_URL}?cc={outcome.completion_code}"
                fake.arrive(pid, outcome.exit_url)
                came_back[pid] = (policy, outcome.completion_code, bot, url)
        assert len(came_back) == 4

        ours = {p.external_ids["PROLIFIC_PID"]: p for p in Participant.objects.filter(study=study)}
        codes = study.crowd["codes"]
        for pid, (policy, code, _, _) in came_back.items():
            assert code == codes[ours[pid].outcome]
        outcomes = {policy: ours[pid].outcome for pid, (policy, *_) in came_back.items()}
        assert outcomes == {"bt": "completed", "inattentive": "failed_attention",
                            "decline": "no_consent"}
        failed_pid, (_, _, failed_bot, failed_url) = next(
            (pid, entry) for pid, entry in came_back.items() if entry[0] == "inattentive")

        # The failed participant tries again: the same browser with a made-up id is
        # refused; a fresh browser with a made-up id and session (the real study id)
        # gets in and completes.
        made_up = secrets.token_hex(12)
        forged = (failed_url.replace(failed_pid, made_up)
                  .replace(next(s["id"] for s in fake.submissions.values()
                                if s["participant"] == failed_pid), secrets.token_hex(12)))
        with pytest.raises(bots.SimulationError, match="HTTP 403"):
            failed_bot.run(forged)
        _, again = take(study, "bt", forged, 99)
        assert again.completion_code == codes["completed"]

        dry = run("prolific", "review", "--study", study.slug, "--dry-run")
        assert "would 2 approve, 1 request return, 0 reject; 1 untouched" in dry
        stranger = Participant.objects.get(external_key=f"PROLIFIC_PID:{made_up}")
        assert (f"flagged: participant {stranger.pk} (outcome completed): no submission of "
                f"{made_up} on Prolific") in dry
        run("prolific", "review", "--study", study.slug)
        statuses = {s["participant"]: (s["status"], bool(s["return_requested"]))
                    for s in fake.submissions.values()}
        expected = {"completed": ("APPROVED", False), "failed_attention": ("AWAITING REVIEW", True),
                    "no_consent": ("AWAITING REVIEW", True)}
        assert statuses == {pid: expected[ours[pid].outcome] for pid in came_back}
        again = run("prolific", "review", "--study", study.slug)
        assert "0 approve, 0 request return, 0 reject" in again

        run("prolific", "review", "--study", study.slug, "--reject-failed")
        after = {s["participant"]: s["status"] for s in fake.submissions.values()}
        assert {pid: after[pid] for pid in came_back} == {
            pid: {"failed_attention": "REJECTED"}.get(ours[pid].outcome, statuses[pid][0])
            for pid in came_back}
