"""The admin's live dashboard of a study: its numbers, its pages, and (in Chromium) that
it refreshes itself when an answer comes in."""

import json
from datetime import timedelta

import pytest
from django.utils import timezone

from studyapp.results import dashboard
from studyapp.participation.bots import USER_AGENT
from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem
from studyapp.results.analysis_page import note_report, report_folder
from studyapp.survey.study_types import list_study_types
from tests.studyapp.conftest import ACTIONS, SOURCES, make_stimuli, make_study

pytestmark = pytest.mark.django_db

PLACES = 10


@pytest.fixture(autouse=True)
def _count_every_answer(settings):
    """Count the exclusions again on every new answer (a busy study waits a while)."""
    settings.STUDY_DASHBOARD_RECOMPUTE_S = 0


def small_study(slug="dash"):
    """Return a study of the default type: 2 conditions x 3 sources, one clip each."""
    study = Study.objects.create(slug=slug, title="Dashboard test", clips_per_trial=3,
                                 max_participants=PLACES, max_failed_catch=1)
    make_stimuli(study)
    return study


def take_part(study, outcome="", times=(9000, 9000), failed_checks=0, agent="", ago=60):
    """Add a participant who answered a main trial per condition in ``times`` ms (None:
    not answered yet) and failed ``failed_checks`` catch trials; return them."""
    now = timezone.now()
    started = now - timedelta(minutes=ago)
    finished = outcome in (Participant.Outcome.COMPLETED, Participant.Outcome.FAILED_ATTENTION)
    person = Participant.objects.create(
        study=study, seed=1, consented_at=started, active_at=started, user_agent=agent,
        outcome=outcome, completed_at=now - timedelta(minutes=1) if finished else None)
    stimuli = {(s.action, s.source): s for s in Stimulus.objects.filter(study=study)}
    kinds = [(Trial.Kind.MAIN, action, ms) for action, ms in zip(ACTIONS, times)]
    kinds += [(Trial.Kind.CATCH, ACTIONS[0], 9000)] * failed_checks
    for index, (kind, action, ms) in enumerate(kinds):
        trial = Trial.objects.create(
            participant=person, index=index, action=action, kind=kind, shown_at=started,
            answered_at=started + timedelta(milliseconds=ms) if ms is not None else None,
            time_ms=ms, catch_passed=False if kind == Trial.Kind.CATCH else None)
        for position, source in enumerate(SOURCES):
            TrialItem.objects.create(trial=trial, stimulus=stimuli[action, source],
                                     position=position, plays=1,
                                     answers={} if ms is None else
                                     {"preference": position + 1})
    return person


@pytest.fixture
def study(settings, tmp_path):
    settings.VAR_DIR = tmp_path / "var"
    study = small_study()
    take_part(study, Participant.Outcome.COMPLETED, times=(4000, 6000))
    take_part(study, Participant.Outcome.COMPLETED, times=(8000, 500), agent=USER_AGENT)
    take_part(study, Participant.Outcome.FAILED_ATTENTION, failed_checks=2)
    take_part(study, times=(10000, None), ago=5)
    Participant.objects.create(study=study, seed=2, outcome=Participant.Outcome.NO_CONSENT,
                               completed_at=timezone.now())
    return study


def outcome(data, key):
    return next(o for o in data["participants"]["outcomes"] if o["outcome"] == key)


def test_participants_by_outcome_with_the_bots_apart(study):
    data = dashboard.dashboard_data(study)
    people = data["participants"]
    assert people["total"] == 5 and people["bots"] == 1
    assert (outcome(data, "completed")["n"], outcome(data, "completed")["bots"]) == (2, 1)
    assert outcome(data, "failed_attention")["n"] == 1
    assert outcome(data, "no_consent")["n"] == 1
    assert outcome(data, dashboard.TAKING_PART)["n"] == 1
    # Finished (3) and taking part (1) hold places; declining holds none.
    assert people["holding"] == 4
    last = people["timeline"]["steps"][-1]["counts"]
    assert sum(last.values()) == 5 and last["completed"] == 2
    svg = dashboard.timeline_svg(people["timeline"])
    assert svg.startswith("<svg") and "<rect" in svg and "Completed" in svg
    assert people["timeline"]["steps"][-1]["bots"] == 1 and 'class="bots"' in svg


def test_judgements_per_source_and_condition_against_the_plan(study):
    data = dashboard.dashboard_data(study)
    per_participant = dashboard.planned_judgements(study)
    assert per_participant == len(ACTIONS) * len(SOURCES)  # one trial per condition, 3 clips
    cells = {(c["condition"], c["source"]): c for c in data["cells"]}
    assert set(cells) == {(a, s) for a in ACTIONS for s in SOURCES}
    # Answered main trials: 4 of the first condition, 3 of the second; catch trials
    # do not count.
    for source in SOURCES:
        assert cells[ACTIONS[0], source]["judgements"] == 4
        assert cells[ACTIONS[1], source]["judgements"] == 3
        assert cells[ACTIONS[0], source]["bots"] == 1
    target = round(PLACES * per_participant / len(cells))
    assert {c["target"] for c in cells.values()} == {target}
    assert cells[ACTIONS[0], SOURCES[0]]["share"] == pytest.approx(4 / target)
    clips = {c["id"]: c for c in data["clips"]}
    assert set(clips) == set(study.stimuli.values_list("pk", flat=True))
    first = Stimulus.objects.get(study=study, action=ACTIONS[0], source=SOURCES[0])
    assert clips[first.pk]["judgements"] == 4
    assert clips[first.pk]["video"] == first.preview_url("mp4")


def test_no_target_without_places(study):
    Study.objects.filter(pk=study.pk).update(max_participants=None)
    study.refresh_from_db()
    data = dashboard.dashboard_data(study)
    assert {c["target"] for c in data["cells"]} == {None}
    assert data["finish"]["eta"] is None and "No places" in data["finish"]["says"]


def test_exclusions_are_the_analysis_rules(study):
    rules = {r["rule"]: r for r in dashboard.dashboard_data(study)["exclusions"]["rules"]}
    failed = rules["Failed more than one attention check"]
    assert (failed["participants"], failed["trials"], failed["judgements"]) == (1, 2, 6)
    fast = rules["Answered before the longest clip of the trial could have played once"]  # the bot's 500 ms trial
    assert (fast["participants"], fast["trials"], fast["judgements"]) == (1, 1, 3)
    # 21 main-trial judgements before exclusions (7 answered main trials x 3 clips).
    assert rules["Main-trial judgements before exclusions"]["judgements"] == 21
    assert rules["Analysed"]["judgements"] == 21 - 6 - 3
    recent = dashboard.dashboard_data(study)["exclusions"]["recent"]
    assert [(e["failed_checks"], e["bot"]) for e in recent] == [(2, False)]


def test_exclusions_follow_new_answers(study):
    before = dashboard.dashboard_data(study)["exclusions"]["rules"][0]["judgements"]
    take_part(study, Participant.Outcome.COMPLETED)
    after = dashboard.dashboard_data(study)["exclusions"]["rules"][0]["judgements"]
    assert after == before + 6


def test_median_time_per_trial_and_session(study):
    timing = dashboard.dashboard_data(study)["timing"]
    # Answered main trials: 4000 6000 8000 500 9000 9000 10000 -> 8000 ms.
    assert timing["median_trial_s"] == pytest.approx(8.0) and timing["n_trials"] == 7
    # Without the bot's 8000 and 500: 4000 6000 9000 9000 10000 -> 9000 ms.
    assert timing["median_trial_people_s"] == pytest.approx(9.0)
    assert timing["session"]["minutes"] == study.duration().minutes
    assert timing["session"]["says"] == study.duration().describe()


def test_predicted_finish_from_the_arrival_rate(study):
    now = timezone.now()
    finish = dashboard.dashboard_data(study, now=now)["finish"]
    # 4 consents, the first 60 minutes ago: 4 per hour; 6 places left: 1.5 hours, then a session.
    assert finish["rate_per_hour"] == pytest.approx(4.0, rel=0.01)
    assert finish["left"] == PLACES - 4
    eta = timezone.datetime.fromisoformat(finish["eta"])
    session = study.duration().seconds
    assert abs((eta - now).total_seconds() - (1.5 * 3600 + session)) < 60


def summary(criterion=""):
    return {
        "study": "dash", "criterion": criterion, "measure": "mean rank", "confidence": 0.95,
        "n_participants": 3, "n_judgements": 18, "order": ["real", "a2m"],
        "sources": {"real": {"score": 1.5, "ci": [1.2, 1.8], "n_participants": 3,
                             "n_judgements": 9},
                    "a2m": {"score": 2.5, "ci": [2.1, 2.9], "n_participants": 3,
                            "n_judgements": 9}},
        "tests": {"pairs": [{"a": "real", "b": "a2m", "p_holm": 0.0123456}]},
        "blindness": {"source: delivery": {"passed": True, "says": "no leak found"},
                      "catch: content": {"passed": False, "says": "told apart"}},
        "notes": ["rough"],
    }


def test_the_latest_analysis_with_its_intervals_and_audit(study):
    assert dashboard.dashboard_data(study)["analysis"] is None
    folder = report_folder(study)
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps(summary()))
    (folder / "report.html").write_text("<html></html>")
    analysis = dashboard.dashboard_data(study)["analysis"]
    part = analysis["criteria"][0]
    assert [s["source"] for s in part["sources"]] == ["real", "a2m"]
    assert part["sources"][0]["ci"] == [1.2, 1.8]
    assert part["tests"][0]["rows"] == [["real", "a2m", "0.0123"]]
    assert [(b["label"], b["passed"]) for b in analysis["blindness"]] == [
        ("source: delivery", True), ("catch: content", False)]


def test_an_analysis_from_the_command_line_elsewhere(study, tmp_path):
    out = tmp_path / "elsewhere"
    out.mkdir()
    (out / "summary.json").write_text(json.dumps(summary() | {"n_participants": 7}))
    (out / "report.html").write_text("<html></html>")
    note_report(study, out)  # what `analyze --study --out elsewhere` does
    assert dashboard.dashboard_data(study)["analysis"]["criteria"][0]["n_participants"] == 7


def test_the_pages_are_for_staff_and_linked_from_the_study(admin_client, client, study):
    page = f"/admin/survey/study/{study.pk}/dashboard/"
    assert client.get(page).status_code == 302  # to the login
    assert client.get(f"{page}data.json").status_code == 302
    text = admin_client.get(page).content.decode()
    for heading in ("Participants by outcome", "Judgements per source and condition",
                    "Exclusions as they happen", "Median time per main trial",
                    "Predicted finish", "Latest analysis", "Clips"):
        assert heading in text
    assert "<svg" in text and "simulated" in text
    body = admin_client.get(f"{page}data.json").json()
    assert body["data"]["participants"]["total"] == 5 and 'data-section="cells"' in body["html"]
    change = admin_client.get(f"/admin/survey/study/{study.pk}/change/").content.decode()
    listing = admin_client.get("/admin/survey/study/").content.decode()
    assert page in change and page in listing


def test_a_staff_member_without_the_view_permission_is_refused(client, study):
    from django.contrib.auth.models import User

    User.objects.create_user("helper", password="pw", is_staff=True)
    client.login(username="helper", password="pw")
    assert client.get(f"/admin/survey/study/{study.pk}/dashboard/data.json").status_code == 403


@pytest.mark.parametrize("agent,is_bot", [(USER_AGENT, True), ("Python-urllib/3.12", True),
                                          ("Mozilla/5.0 (X11; Linux x86_64)", False)])
def test_bots_are_told_by_their_user_agent(settings, tmp_path, agent, is_bot):
    settings.VAR_DIR = tmp_path
    study = small_study("bots")
    take_part(study, Participant.Outcome.COMPLETED, agent=agent)
    assert dashboard.dashboard_data(study)["participants"]["bots"] == int(is_bot)


@pytest.mark.parametrize("key", list_study_types())
def test_every_study_type_has_its_dashboard(admin_client, make_bot, media_root, clips, extra_clips,
                                            settings, tmp_path, key):
    """Played by the test bot through the real pages: the dashboard counts what the
    export holds, with the analysis' exclusion table, for a study of every type."""
    settings.VAR_DIR = tmp_path / "var"
    study = make_study(key, clips, extra_clips, catch=True, max_participants=3)
    bot = make_bot(study)
    bot.join()
    bot.finish()
    data = dashboard.dashboard_data(study)
    main = TrialItem.objects.judged().filter(trial__participant__study=study,
                                             trial__kind=Trial.Kind.MAIN,
                                             trial__answered_at__isnull=False,
                                             stimulus__role=Stimulus.Role.JUDGED).count()
    assert main and data["judgements"] == main
    assert data["per_participant"] == main  # the planned session is the one they took
    rules = data["exclusions"]["rules"]
    assert rules and rules[0]["rule"] == "Main-trial judgements before exclusions"
    response = admin_client.get(f"/admin/survey/study/{study.pk}/dashboard/")
    assert response.status_code == 200
    assert f'data-clip="{study.stimuli.first().pk}"' in response.content.decode()


@pytest.mark.django_db(transaction=True)
def test_simulate_participants_bots_are_marked(live_server, media_root, clips, settings, tmp_path):
    """The bots of ``simulate_participants`` (over real HTTP) are counted as bots."""
    from io import StringIO

    from django.core.management import call_command

    from tests.studyapp.conftest import make_ranking_study

    settings.VAR_DIR = tmp_path / "var"
    study = make_ranking_study(clips)
    call_command("simulate_participants", study=study.slug, url=live_server.url, n=2, pace=0,
                 seed=1, stdout=StringIO())
    people = dashboard.dashboard_data(study)["participants"]
    assert people["total"] == people["bots"] == 2
    assert set(Participant.objects.filter(study=study).values_list("user_agent", flat=True)) == {
        USER_AGENT}


def test_a_refresh_plans_no_session_and_reads_no_table(study, monkeypatch,
                                                       django_assert_max_num_queries):
    """Once computed for the answers as they are, the planned session, the session
    estimate and the exclusions come from the cache (a Prolific study's time limit
    follows its minutes)."""
    from studyapp.results import export

    codes = {"completed": "C0MPL3TE", "failed_attention": "FA1LED00", "no_consent": "N0C0NSNT"}
    Study.objects.filter(pk=study.pk).update(crowd={"platform": "prolific", "codes": codes},
                                             catch_trials=2)
    study.refresh_from_db()
    first = dashboard.dashboard_data(study)

    def refused(*args, **kwargs):
        raise AssertionError("computed again")

    monkeypatch.setattr(type(study.kind), "plan_trials", refused)
    monkeypatch.setattr(export, "responses_frame", refused)
    with django_assert_max_num_queries(20):
        again = dashboard.dashboard_data(study)
    assert again["exclusions"]["rules"] == first["exclusions"]["rules"]
    assert again["participants"]["holding"] == first["participants"]["holding"]
    assert again["timing"]["session"] == first["timing"]["session"]


def test_an_analyze_run_with_its_audit_shows(make_bot, media_root, clips, settings, tmp_path):
    """``analyze --study --out`` elsewhere, blindness audit included: the dashboard shows
    its sources with their intervals and the audit's verdicts."""
    from io import StringIO

    from django.core.management import call_command

    from tests.studyapp.conftest import make_ranking_study

    settings.VAR_DIR = tmp_path / "var"
    study = make_ranking_study(clips, max_participants=3)
    for n in range(3):
        bot = make_bot(study)
        bot.join(PROLIFIC_PID=f"person-{n}")
        bot.finish()
    out = tmp_path / "elsewhere"
    call_command("analyze", study=study.slug, out=str(out), bootstrap=20, min_time_factor=0.0,
                 stdout=StringIO(), stderr=StringIO())
    written = json.loads((out / "summary.json").read_text())
    analysis = dashboard.dashboard_data(study)["analysis"]
    part = analysis["criteria"][0]
    assert [s["source"] for s in part["sources"]] == written["order"]
    assert [s["ci"] for s in part["sources"]] == [written["sources"][name]["ci"]
                                                  for name in written["order"]]
    assert part["n_participants"] == 3
    assert {b["label"] for b in analysis["blindness"]} == set(written["blindness"])
    assert all(b["says"] for b in analysis["blindness"])


def test_a_busy_study_counts_its_exclusions_at_most_so_often(study, settings):
    settings.STUDY_DASHBOARD_RECOMPUTE_S = 60
    first = dashboard.dashboard_data(study)
    take_part(study, Participant.Outcome.COMPLETED)
    again = dashboard.dashboard_data(study)
    assert again["judgements"] == first["judgements"] + 6  # counted on every refresh
    assert again["exclusions"]["rules"] == first["exclusions"]["rules"]  # kept a while
    assert again["exclusions"]["counted_at"] == first["exclusions"]["counted_at"]
    Study.objects.filter(pk=study.pk).update(max_failed_catch=2)  # a setting: at once
    study.refresh_from_db()
    changed = {r["rule"] for r in dashboard.dashboard_data(study)["exclusions"]["rules"]}
    assert "Failed more than 2 attention checks" in changed
    settings.STUDY_DASHBOARD_RECOMPUTE_S = 0
    rules = dashboard.dashboard_data(study)["exclusions"]["rules"]
    assert rules[0]["judgements"] == first["exclusions"]["rules"][0]["judgements"] + 6
