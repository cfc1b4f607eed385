"""Prolific end to end: `prolific create` makes the study on the local server that follows
Prolific's published API, simulated participants take it through our real pages (bt,
inattentive and declining bots), come back to Prolific through the redirect our last
page sent them to, and `prolific review` approves and returns exactly as our exclusions
say."""

import re
from io import StringIO

import pytest
from django.core.management import call_command

from studyapp.survey import bots
from studyapp.survey.models import Participant
from tests.studyapp.conftest import make_study
from tests.studyapp.prolific_fake import COMPLETE_URL, FakeProlific

pytestmark = [pytest.mark.slow, pytest.mark.django_db(transaction=True)]

TOKEN = "test-token"
LINE = re.compile(r"^(?P<pid>[0-9a-f]{24}): \d+ trials, outcome (?P<outcome>\w*)"
                  r"(?:, redirect (?P<redirect>[^,\s]+))?, completion code (?P<code>\S*)$")
RUNS = {"bt": (11, 2), "inattentive": (12, 1), "decline": (13, 1)}  # policy: (seed, bots)


def run(*args) -> str:
    out = StringIO()
    call_command(*args, stdout=out, stderr=StringIO())
    return out.getvalue()


def test_prolific_study_from_creation_to_review(transactional_db, media_root, clips, extra_clips,
                                                live_server, monkeypatch):
    study = make_study("ranking", clips, extra_clips, slug="prolific-e2e", catch=True,
                       trials_per_participant=2, max_participants=10)
    with FakeProlific(token=TOKEN) as fake:
        monkeypatch.setenv("PROLIFIC_TOKEN", TOKEN)
        monkeypatch.setenv("PROLIFIC_API_URL", fake.url)
        run("prolific", "create", "--study", study.slug, "--base-url", live_server.url,
            "--review-completed")
        run("prolific", "publish", "--study", study.slug)
        study.refresh_from_db()
        remote = fake.studies[study.crowd["prolific_study_id"]]
        assert remote["external_study_url"].startswith(f"{live_server.url}/s/{study.slug}/?")

        came_back = {}
        for policy, (seed, n) in RUNS.items():
            for i in range(1, n + 1):  # they open the study on Prolific first
                fake.start(remote["id"], bots.person_id(seed, i))
            out = run("simulate_participants", "--study", study.slug, "--url", live_server.url,
                      "--policy", policy, "--seed", str(seed), "--n", str(n), "--pace", "0")
            for line in out.splitlines()[:-1]:
                bot = LINE.match(line).groupdict()
                assert bot["redirect"] == f"{COMPLETE_URL}?cc={bot['code']}"
                fake.arrive(bot["pid"], bot["redirect"])
                came_back[bot["pid"]] = (policy, bot["outcome"], bot["code"])
        assert len(came_back) == 4

        ours = {p.external_ids["PROLIFIC_PID"]: p for p in Participant.objects.filter(study=study)}
        codes = study.crowd["codes"]
        for pid, (policy, outcome, code) in came_back.items():
            assert ours[pid].outcome == outcome and code == codes[outcome]
        outcomes = {policy: outcome for policy, outcome, _ in came_back.values()}
        assert outcomes == {"bt": "completed", "inattentive": "failed_attention",
                            "decline": "no_consent"}

        dry = run("prolific", "review", "--study", study.slug, "--dry-run")
        assert "would 2 approve, 1 request return, 0 reject; 1 untouched" in dry
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
