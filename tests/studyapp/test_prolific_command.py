"""manage.py prolific: every subcommand against the local server that follows Prolific's
published API documentation (tests/studyapp/prolific_fake.py)."""

import json
from io import StringIO

import pytest
from django.core.management import call_command
from django.core.management.base import CommandError
from django.utils import timezone

from studyapp.survey.models import Participant, Study, Trial
from tests.studyapp.prolific_fake import COMPLETE_URL, FakeProlific

TOKEN = "test-token"
BASE = "https://study.example"


@pytest.fixture
def fake(monkeypatch):
    with FakeProlific(token=TOKEN) as server:
        monkeypatch.setenv("PROLIFIC_TOKEN", TOKEN)
        monkeypatch.setenv("PROLIFIC_API_URL", server.url)
        yield server


@pytest.fixture
def study(db):
    return Study.objects.create_study("ranking", "motion-prolific", "Movement study",
                                      max_participants=20, catch_trials=1)


def prolific(*args, **kwargs) -> str:
    out = StringIO()
    call_command("prolific", *args, stdout=out, stderr=StringIO(), **kwargs)
    return out.getvalue()


def json_in(text: str) -> dict:
    return json.loads(text[text.index("{"):text.rindex("}") + 1])


def created(study, fake, *extra) -> dict:
    """Create and publish the Prolific study of ``study``; return it as the server has it."""
    prolific("create", "--study", study.slug, "--base-url", BASE, *extra)
    prolific("publish", "--study", study.slug)
    study.refresh_from_db()
    return fake.studies[study.crowd["prolific_study_id"]]


def person(study, pid, outcome="", failed_catch=0):
    """Add our participant with Prolific id ``pid`` who ended with ``outcome``."""
    now = timezone.now()
    code = study.platform.code_for(outcome) if outcome else ""
    p = Participant.objects.create(
        study=study, seed=1, external_ids={"PROLIFIC_PID": pid},
        external_key=f"PROLIFIC_PID:{pid}", consented_at=now, outcome=outcome,
        completed_at=now if outcome else None, completion_code=code)
    for index in range(failed_catch):
        Trial.objects.create(participant=p, index=index, action="walk", kind="catch",
                             catch_passed=False, answered_at=now)
    return p


def came_back(fake, prolific_study, pid, code):
    """Prolific participant ``pid`` starts the study and returns with ``code``."""
    fake.start(prolific_study["id"], pid)
    return fake.arrive(pid, f"{COMPLETE_URL}?cc={code}")


# create


def test_create_dry_run_prints_the_documented_json_and_sends_nothing(fake, study):
    out = prolific("create", "--study", study.slug, "--base-url", BASE, "--dry-run")
    payload = json_in(out)
    assert payload["external_study_url"] == (
        f"{BASE}/s/{study.slug}/?PROLIFIC_PID={{{{%PROLIFIC_PID%}}}}&STUDY_ID={{{{%STUDY_ID%}}}}"
        f"&SESSION_ID={{{{%SESSION_ID%}}}}")
    assert payload["prolific_id_option"] == "url_parameters"
    assert payload["total_available_places"] == 20
    minutes = study.minutes()  # estimated from its trials and clips
    assert payload["estimated_completion_time"] == minutes
    assert payload["reward"] == -(-minutes * 900 // 60)  # at 900 cents an hour
    assert f"Duration: estimated " in out
    assert payload["name"] == "Movement study" and payload["description"] == study.shown_consent()
    kinds = {c["code_type"]: c["actions"] for c in payload["completion_codes"]}
    assert kinds == {
        "COMPLETED": [{"action": "AUTOMATICALLY_APPROVE"}],
        "FAILED_ATTENTION_CHECK": [{"action": "MANUALLY_REVIEW"}],
        "NO_CONSENT": [{"action": "REQUEST_RETURN", "return_reason": "Withdrew consent."}],
    }
    assert "Would generate completion codes for completed, failed_attention, no_consent" in out
    assert "Dry run: nothing was sent" in out and fake.log == []
    study.refresh_from_db()
    assert study.crowd == {}


def test_create_makes_a_draft_and_stores_its_id_and_codes(fake, study):
    out = prolific("create", "--study", study.slug, "--base-url", BASE)
    study.refresh_from_db()
    crowd = study.crowd
    assert crowd["platform"] == "prolific" and set(crowd["codes"]) == {
        "completed", "failed_attention", "no_consent"}
    assert "Generated completion codes for completed, failed_attention, no_consent" in out
    draft = fake.studies[crowd["prolific_study_id"]]
    assert draft["status"] == "UNPUBLISHED"
    assert {c["code"] for c in draft["completion_codes"]} == set(crowd["codes"].values())
    assert f"Created draft Prolific study {draft['id']}" in out
    assert study.platform.code_for("failed_attention") == crowd["codes"]["failed_attention"]
    with pytest.raises(CommandError, match="already has Prolific study.*--force"):
        prolific("create", "--study", study.slug, "--base-url", BASE)
    again = prolific("create", "--study", study.slug, "--base-url", BASE, "--force")
    study.refresh_from_db()
    assert study.crowd["codes"] == crowd["codes"] and "Generated" not in again
    assert study.crowd["prolific_study_id"] != crowd["prolific_study_id"] and len(fake.studies) == 2


def test_create_keeps_the_studys_own_codes_and_time_limit(fake, study):
    study.crowd = {"platform": "prolific", "codes": {"completed": "CMINE001"},
                   "time_limit_minutes": 30,
                   "screening": [{"question": "Do you have normal vision?"}]}
    study.save()
    out = prolific("create", "--study", study.slug, "--base-url", BASE, "--reward-cents", "200",
                   "--minutes", "12", "--places", "5", "--screen-out-reward-cents", "20",
                   "--review-completed")
    study.refresh_from_db()
    draft = fake.studies[study.crowd["prolific_study_id"]]
    codes = {c["code_type"]: c for c in draft["completion_codes"]}
    assert codes["COMPLETED"]["code"] == "CMINE001"
    assert codes["COMPLETED"]["actions"] == [{"action": "MANUALLY_REVIEW"}]
    assert codes["FIXED_SCREENOUT"]["actions"] == [
        {"action": "FIXED_SCREEN_OUT_PAYMENT", "fixed_screen_out_reward": 20, "slots": 5}]
    assert codes["FIXED_SCREENOUT"]["code"] == study.crowd["codes"]["screened_out"]
    assert (draft["reward"], draft["estimated_completion_time"], draft["total_available_places"],
            draft["maximum_allowed_time"]) == (200, 12, 5, 30)
    assert "failed_attention, no_consent, screened_out" in out and "CMINE001" not in out


def test_create_mistakes_are_clear(fake, study, monkeypatch):
    study.max_participants = None
    study.save()
    with pytest.raises(CommandError, match="no max_participants.*--places N"):
        prolific("create", "--study", study.slug, "--base-url", BASE)
    with pytest.raises(CommandError, match="less than the reward"):
        prolific("create", "--study", study.slug, "--places", "3", "--reward-cents", "50",
                 "--screen-out-reward-cents", "60", "--dry-run")
    with pytest.raises(CommandError, match="--devices: fridge"):
        prolific("create", "--study", study.slug, "--places", "3", "--devices", "fridge",
                 "--dry-run")
    monkeypatch.delenv("PROLIFIC_TOKEN")
    with pytest.raises(CommandError, match="PROLIFIC_TOKEN is not set"):
        prolific("create", "--study", study.slug, "--places", "3")
    study.crowd = {"platform": "generic", "id_param": "participantId"}
    study.save()
    with pytest.raises(CommandError, match="platform 'generic'.*needs platform prolific"):
        prolific("create", "--study", study.slug, "--places", "3", "--dry-run")
    with pytest.raises(CommandError, match="Unknown study 'nope'"):
        prolific("create", "--study", "nope")
    study.refresh_from_db()
    assert "prolific_study_id" not in study.crowd and fake.studies == {}


def test_the_stored_prolific_id_is_checked():
    from studyapp.crowd.platform import make_platform

    settings = {"platform": "prolific", "codes": {"completed": "C1"}}
    assert make_platform({**settings, "prolific_study_id": "60AACA280709EE40EC37D4885"[:24]})
    with pytest.raises(ValueError, match="crowd.prolific_study_id: 'my study' must be the 24 hex"):
        make_platform({**settings, "prolific_study_id": "my study"})


# publish, stop, submissions


def test_publish_and_stop_transition_the_prolific_study(fake, study):
    prolific("create", "--study", study.slug, "--base-url", BASE)
    study.refresh_from_db()
    prolific_id = study.crowd["prolific_study_id"]
    assert "PUBLISH sent; status ACTIVE" in prolific("publish", "--study", study.slug)
    assert fake.requests("POST", "/transition/")[-1]["body"] == {"action": "PUBLISH"}
    assert "STOP sent; status AWAITING REVIEW" in prolific("stop", "--study", study.slug)
    assert fake.studies[prolific_id]["status"] == "AWAITING REVIEW"
    with pytest.raises(CommandError, match="refused study .*Cannot stop a study that is "
                                           "AWAITING REVIEW"):
        prolific("stop", "--study", study.slug)


def test_publish_mistakes_are_clear(fake, study):
    with pytest.raises(CommandError, match="no Prolific study yet.*prolific create"):
        prolific("publish", "--study", study.slug)
    study.crowd = {"platform": "prolific", "codes": {"completed": "C1"},
                   "prolific_study_id": "b" * 24}
    study.save()
    with pytest.raises(CommandError, match=f"no study {'b' * 24} \\(404"):
        prolific("publish", "--study", study.slug)
    study.status = Study.Status.CLOSED
    study.save()
    with pytest.raises(CommandError, match="is closed.*open it first"):
        prolific("publish", "--study", study.slug)


def test_submissions_are_listed_beside_our_outcomes(fake, study):
    remote = created(study, fake)
    codes = study.crowd["codes"]
    person(study, "a" * 24, "completed")
    person(study, "b" * 24)
    came_back(fake, remote, "a" * 24, codes["completed"])
    fake.start(remote["id"], "b" * 24)
    fake.start(remote["id"], "c" * 24)
    rows = [json.loads(line) for line in
            prolific("submissions", "--study", study.slug, "--json").splitlines()]
    assert [(r["participant_id"][0], r["status"], r["study_code"], r["outcome"]) for r in rows] == [
        ("a", "APPROVED", codes["completed"], "completed"),
        ("b", "ACTIVE", None, "taking part"),
        ("c", "ACTIVE", None, "unknown"),
    ]
    table = prolific("submissions", "--study", study.slug)
    assert "3 submission(s)" in table and "participant_id\tstatus" in table


# review


@pytest.fixture
def reviewed(fake, study):
    """A published study whose submissions are in every state review meets."""
    remote = created(study, fake, "--review-completed")
    codes = study.crowd["codes"]
    cases = {
        "ok": ("1" * 24, "completed", codes["completed"]),
        "failed": ("2" * 24, "failed_attention", codes["failed_attention"]),
        "declined": ("3" * 24, "no_consent", codes["no_consent"]),
        "excluded": ("4" * 24, "completed", codes["completed"]),  # 1 failed catch trial
        "taking_part": ("5" * 24, "", "NOCODE"),
        "unknown": ("6" * 24, None, codes["completed"]),
        "timed_out": ("7" * 24, "timed_out", "NOCODE"),
    }
    study.max_failed_catch = 1
    study.save()
    for name, (pid, outcome, code) in cases.items():
        if outcome is not None:
            failed = {"excluded": 1, "failed": 2}.get(name, 0)
            person(study, pid, outcome, failed_catch=failed)
        came_back(fake, remote, pid, code)
    person(study, "8" * 24)
    fake.start(remote["id"], "8" * 24)  # still active on Prolific
    return {name: pid for name, (pid, _, _) in cases.items()} | {"active": "8" * 24}


def status_of(fake, pid):
    submission = next(s for s in fake.submissions.values() if s["participant"] == pid)
    return submission["status"], bool(submission["return_requested"])


def test_review_dry_run_shows_every_decision_and_sends_nothing(fake, study, reviewed):
    posts = len(fake.requests("POST"))
    out = prolific("review", "--study", study.slug, "--dry-run", "--max-failed-catch", "0")
    assert len(fake.requests("POST")) == posts
    lines = {line.split(": ", 1)[1].split(" ", 1)[0]: line.split(":", 1)[0]
             for line in out.splitlines() if ": " in line and "(" in line}
    assert lines == {
        reviewed["ok"]: "would approve",
        reviewed["failed"]: "would request return",
        reviewed["declined"]: "nothing to do",  # its code asked for the return already
        reviewed["excluded"]: "would request return",
        reviewed["taking_part"]: "left alone",
        reviewed["unknown"]: "left alone",
        reviewed["timed_out"]: "left alone",
        reviewed["active"]: "nothing to do",
    }
    assert "failed 1 of 1 attention check(s), more than 0" in out
    assert "not a participant of ours" in out and "still taking part in our study" in out
    assert ("Dry run: would 1 approve, 2 request return, 0 reject; 5 untouched. Nothing was "
            "sent.") in out


def test_review_acts_by_our_exclusions_and_twice_is_once(fake, study, reviewed):
    out = prolific("review", "--study", study.slug)
    assert "Reviewed 8 submission(s): 2 approve, 1 request return, 0 reject; 5 untouched." in out
    assert status_of(fake, reviewed["ok"]) == ("APPROVED", False)
    assert status_of(fake, reviewed["failed"]) == ("AWAITING REVIEW", True)
    assert status_of(fake, reviewed["excluded"]) == ("APPROVED", False)  # the study's own rule
    for untouched in ("taking_part", "unknown", "timed_out"):
        assert status_of(fake, reviewed[untouched]) == ("AWAITING REVIEW", False)
    assert status_of(fake, reviewed["active"]) == ("ACTIVE", False)
    returns = fake.requests("POST", "/request-return/")
    assert [r["body"] for r in returns] == [
        {"request_return_reasons": ["Failed the study's attention checks."]}]
    posts = len(fake.requests("POST"))
    again = prolific("review", "--study", study.slug)
    assert len(fake.requests("POST")) == posts
    assert "0 approve, 0 request return, 0 reject" in again


def test_review_rejects_failed_attention_when_asked(fake, study, reviewed):
    with pytest.raises(CommandError, match="at least 100"):
        prolific("review", "--study", study.slug, "--reject-failed", "--reject-message", "No.")
    out = prolific("review", "--study", study.slug, "--reject-failed",
                   "--max-failed-catch", "0")
    # Prolific allows a rejection only after two failed checks: one is asked to return.
    assert "1 approve, 1 request return, 1 reject" in out
    assert status_of(fake, reviewed["failed"])[0] == "REJECTED"
    assert status_of(fake, reviewed["excluded"]) == ("AWAITING REVIEW", True)
    assert "1 failed check(s): Prolific allows a rejection only after 2" in out
    reject = fake.requests("POST", "/transition/")[-1]["body"]
    assert reject["action"] == "REJECT" and reject["rejection_category"] == "FAILED_CHECK"
    assert len(reject["message"]) >= 100
    assert status_of(fake, reviewed["declined"]) == ("AWAITING REVIEW", True)


def test_review_stops_clearly_when_prolific_fails_and_resumes(fake, study, reviewed):
    fake.throttle("/request-return/", times=10, retry_after="0")
    with pytest.raises(CommandError, match="rate-limiting.*run it again to finish"):
        prolific("review", "--study", study.slug)
    assert status_of(fake, reviewed["ok"]) == ("APPROVED", False)
    fake.throttles.clear()
    out = prolific("review", "--study", study.slug)
    assert "0 approve, 1 request return" in out


# bonus


@pytest.fixture
def paid_study(fake, study):
    remote = created(study, fake)
    for pid, outcome in (("a" * 24, "completed"), ("b" * 24, "completed"),
                         ("c" * 24, "failed_attention")):
        person(study, pid, outcome)
        came_back(fake, remote, pid, study.crowd["codes"][outcome])
    return remote


def bonuses_of(fake):
    return {s["participant"][0]: s["bonus_payments"] for s in fake.submissions.values()}


def test_bonus_from_a_csv_is_set_up_then_paid_once(fake, study, paid_study, tmp_path):
    sheet = tmp_path / "bonus.csv"
    sheet.write_text(f"participant_id,amount\n{'a' * 24},0.50\n{'B' * 24},1.25\n")
    out = prolific("bonus", "--study", study.slug, "--csv", str(sheet), "--dry-run")
    assert f"{'a' * 24},0.50\n{'b' * 24},1.25" in out and "1.75 in all" in out
    assert not fake.requests("POST", "bonus")
    out = prolific("bonus", "--study", study.slug, "--csv", str(sheet))
    setup = fake.requests("POST", "/submissions/bonus-payments/")[0]["body"]
    assert setup == {"study_id": paid_study["id"],
                     "csv_bonuses": f"{'a' * 24},0.50\n{'b' * 24},1.25"}
    assert bonuses_of(fake) == {"a": [50], "b": [125], "c": []}
    assert "amount 175" in out and "being processed" in out
    again = prolific("bonus", "--study", study.slug, "--csv", str(sheet))
    assert "already has bonus payment(s) [50]" in again and "No bonuses to pay." in again
    assert bonuses_of(fake) == {"a": [50], "b": [125], "c": []}


def test_bonus_by_outcome(fake, study, paid_study):
    prolific("bonus", "--study", study.slug, "--amount-cents", "30", "--outcome", "completed")
    assert bonuses_of(fake) == {"a": [30], "b": [30], "c": []}
    with pytest.raises(CommandError, match="needs --outcome"):
        prolific("bonus", "--study", study.slug, "--amount-cents", "30")
    with pytest.raises(CommandError, match="no approved or awaiting-review submission.*no_consent"):
        prolific("bonus", "--study", study.slug, "--amount-cents", "30", "--outcome", "no_consent")


def test_bonus_mistakes_pay_nothing(fake, study, paid_study, tmp_path):
    sheet = tmp_path / "bonus.csv"
    sheet.write_text(f"{'a' * 24},50\n{'b' * 24},0.5x\nnobody,1.00\n{'c' * 24}\n")
    with pytest.raises(CommandError, match=r"nothing was paid.*line 1: 50 is not between 0.01 and "
                                           r"20.00.*line 2: '0.5x' is not an amount.*line 3: "
                                           r"'nobody' is not a Prolific.*line 4: 1 column"):
        prolific("bonus", "--study", study.slug, "--csv", str(sheet))
    sheet.write_text(f"{'d' * 24},1.00\n")
    with pytest.raises(CommandError, match=f"no submission in this study: {'d' * 24}"):
        prolific("bonus", "--study", study.slug, "--csv", str(sheet))
    assert not fake.requests("POST", "bonus") and bonuses_of(fake)["a"] == []


def test_review_decisions_follow_the_analysis_rules():
    from studyapp.crowd.prolific import review

    submission = {"id": "s1", "participant_id": "A" * 24, "status": "AWAITING REVIEW",
                  "study_code": "CCOPIED1"}
    row = {"participant": 3, "outcome": "completed", "completion_code": "COURS001",
           "failed_catch": 0, "n_catch": 2, "inconsistent_repeats": 2}
    people = {"a" * 24: row}
    kept = review.decide(submission, people, review.Rules())
    assert (kept.action, kept.participant) == (review.APPROVE, 3)
    assert kept.note == "entered code CCOPIED1, we gave COURS001"  # decided by us, not the code
    strict = review.decide(submission, people, review.Rules(max_failed_repeats=1))
    assert strict.action == review.RETURN
    assert strict.why == "answered 2 repeated trial(s) differently, more than 1"
    with pytest.raises(ValueError, match="0 or more"):
        review.Rules(max_failed_catch=-1)
    # Our participant came with another session than this submission: left to the researcher.
    other = review.decide(submission, {"a" * 24: {**row, "SESSION_ID": "f" * 24}}, review.Rules())
    assert other.action == review.LEAVE and f"session {'f' * 24}" in other.why
    assert review.decide(submission, {"a" * 24: {**row, "SESSION_ID": "S1"}},
                         review.Rules()).action == review.APPROVE


def test_participants_whose_ids_prolific_does_not_know_are_flagged(fake, study):
    remote = created(study, fake)
    known = person(study, "a" * 24, "completed")
    submission, _ = fake.start(remote["id"], "a" * 24)
    known.external_ids = {"PROLIFIC_PID": "a" * 24, "SESSION_ID": submission["id"]}
    known.save()
    stranger = person(study, "b" * 24, "completed")  # never started on Prolific
    wrong = person(study, "c" * 24, "completed")
    fake.start(remote["id"], "c" * 24)
    wrong.external_ids = {"PROLIFIC_PID": "c" * 24, "SESSION_ID": "d" * 24}
    wrong.save()
    out = prolific("review", "--study", study.slug, "--dry-run")
    flagged = [line for line in out.splitlines() if line.startswith("flagged:")]
    assert flagged == [
        f"flagged: participant {stranger.pk} (outcome completed): no submission of {'b' * 24} "
        f"on Prolific; a made-up id? Their answers stay in the export with their ids.",
        f"flagged: participant {wrong.pk} (outcome completed): {'c' * 24} has no submission "
        f"{'d' * 24} on Prolific; a made-up id? Their answers stay in the export with their ids.",
    ]
    listing = prolific("submissions", "--study", study.slug)
    assert f"flagged: participant {stranger.pk}: no submission of {'b' * 24}" in listing


def test_the_readmes_crowd_examples_are_valid_settings():
    import re
    from types import SimpleNamespace

    import yaml

    from studyapp.crowd.platform import make_platform
    from tests.conftest import ROOT

    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Crowd platforms"):text.index("## Results and benchmarks")]
    blocks = re.findall(r"```yaml\n(.*?)```", section, re.S)
    assert blocks
    for block in blocks:
        platform = make_platform(yaml.safe_load(block)["study"]["crowd"])
        person = SimpleNamespace(external_ids={platform.id_params[0]: "12345"},
                                 completion_code="C1", study=None)
        name = platform.id_params[0]
        assert platform.read_ids({name: "12345"})[1] == f"{name}:12345"
        assert platform.completion_url(person) == platform.template.format(code="C1", id="12345")


def test_create_takes_places_and_minutes_from_a_plan(fake, study, tmp_path):
    table = tmp_path / "plan.csv"
    table.write_text("participants,clips,power,width,minutes,reward,cost\n"
                     "20,2,0.41,1.2,7.2,1.44,38.4\n40,8,0.83,0.7,7.2,1.44,76.8\n"
                     "80,8,0.97,0.5,7.2,1.44,153.6\n")
    out = prolific("create", "--study", study.slug, "--base-url", BASE, "--dry-run",
                   "--plan", str(table))
    payload = json_in(out)
    assert payload["total_available_places"] == 40 and payload["estimated_completion_time"] == 8
    assert "From the plan: 40 participants and 8 clips per source and condition (83% power)" in out
    kept = json_in(prolific("create", "--study", study.slug, "--base-url", BASE, "--dry-run",
                            "--plan", str(table), "--places", "25"))
    assert kept["total_available_places"] == 25
    with pytest.raises(CommandError, match="has no column"):
        bad = tmp_path / "bad.csv"
        bad.write_text("a,b\n1,2\n")
        prolific("create", "--study", study.slug, "--base-url", BASE, "--dry-run", "--plan", str(bad))
