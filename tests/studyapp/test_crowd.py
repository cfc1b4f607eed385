"""Crowd platforms and the server's watch rule: Prolific ids, completion codes per outcome
and the redirect (through real HTTP with simulated participants), places and time limits,
a generic platform; answers taken only from people whose clips were fetched and played."""

import re
import time
from datetime import timedelta
from io import StringIO

import pytest
from django.core.exceptions import ValidationError
from django.core.management import call_command
from django.core.management.base import CommandError
from django.utils import timezone

from studyapp.crowd.platform import make_platform
from studyapp.results.export import participants_frame, responses_frame
from studyapp.survey.models import Participant, Study, Trial, TrialItem
from tests.studyapp.conftest import SOURCES, make_stimuli, make_study

pytestmark = pytest.mark.django_db

CODES = {"completed": "C0MPL3TE", "failed_attention": "FA1LED00", "no_consent": "N0C0NSNT",
         "screened_out": "SCR33N00"}
PROLIFIC = {"platform": "prolific", "codes": CODES, "time_limit_minutes": 30,
            "screening": [{"question": "Can you see moving figures clearly on this screen?",
                           "answers": ["Yes", "No"], "accept": ["Yes"]}]}
PID = "5f3a9c2e1b4d6a7f8e9c0b1a"
STUDY = "60aaca280709ee40ec37d488"


def ids(pid, session=None):
    """Return Prolific's three ids of an entry link: ``pid`` and a session of its own."""
    return {"PROLIFIC_PID": pid, "STUDY_ID": STUDY,
            "SESSION_ID": session or pid[::-1]}


@pytest.fixture
def prolific_study(media_root, clips, extra_clips):
    # Two attention checks of both kinds: failing both fails (max_failed_catch 1).
    return make_study("ranking", clips, extra_clips, slug="on-prolific", catch=True,
                      instructed_checks=1, crowd=PROLIFIC)


def test_prolific_ids_are_normalised_and_one_id_takes_a_study_once(prolific_study, make_bot):
    bot = make_bot(prolific_study)
    session = "ABCDEF" * 4
    bot.enter(PROLIFIC_PID=f"  {PID.upper()} ", STUDY_ID=STUDY.upper(), SESSION_ID=session)
    bot.consent(screen_0="Yes")
    person = Participant.objects.get()
    assert person.external_ids == {"PROLIFIC_PID": PID, "STUDY_ID": STUDY,
                                   "SESSION_ID": session.lower()}
    again = make_bot(prolific_study)  # another browser, the same person in other letters
    response = again.enter(**ids(PID.upper(), session))
    assert response.redirect_chain[-1][0].endswith("/instructions/")  # resumes
    again.consent(screen_0="Yes")
    assert Participant.objects.count() == 1


@pytest.mark.parametrize("query, page", [({}, b"missing your participant id"),
                                         ({"PROLIFIC_PID": "not-an-id"}, b"id is not valid")])
def test_entry_without_a_valid_prolific_id_gets_a_clear_page(prolific_study, make_bot, query,
                                                            page):
    bot = make_bot(prolific_study)
    response = bot.enter(**query)
    assert response.status_code == 400 and page in response.content
    assert b"Prolific" in response.content
    assert bot.consent(screen_0="Yes").status_code == 200  # posting consent directly
    assert b"missing your participant id" in bot.consent(screen_0="Yes").content
    assert not Participant.objects.exists()


def test_settings_of_a_platform_are_checked():
    with pytest.raises(ValueError, match="needs the completion code of its 'completed'"):
        make_platform({"platform": "prolific"})
    with pytest.raises(ValueError, match="crowd.codes.finished: not an outcome"):
        make_platform({"platform": "prolific", "codes": {"finished": "X"}})
    with pytest.raises(ValueError, match="crowd.platform: 'mturk' is not a platform"):
        make_platform({"platform": "mturk"})
    with pytest.raises(ValueError, match="crowd.id_param"):
        make_platform({"platform": "generic"})
    with pytest.raises(ValidationError, match="time_limit_minutes"):
        Study.objects.create_study("ranking", "bad", "Bad", crowd={"time_limit_minutes": 0})


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("policy, outcome", [("prefer-real", "completed"), ("inattentive", "failed_attention"),
                                             ("decline", "no_consent"),
                                             ("screen-out", "screened_out")])
def test_each_prolific_outcome_gets_its_code_and_redirect(prolific_study, live_server, policy,
                                                         outcome):
    out = StringIO()
    call_command("simulate_participants", study=prolific_study.slug, n=2, url=live_server.url,
                 policy=policy, seed=1, stdout=out, concurrency=2)
    code = CODES[outcome]
    lines = [line for line in out.getvalue().splitlines() if "completion code" in line]
    assert len(lines) == 2
    for line in lines:
        assert line.endswith(f"completion code {code}")
        assert f"outcome {outcome}" in line
        assert f"redirect https://app.prolific.com/submissions/complete?cc={code}" in line
    people = participants_frame(prolific_study)
    assert people["outcome"].tolist() == [outcome] * 2
    assert people["completion_code"].tolist() == [code] * 2
    if outcome in ("no_consent", "screened_out"):
        assert not Trial.objects.exists()  # they never started


def test_places_count_finished_and_active_people_and_the_time_limit_frees_them(
        prolific_study, make_bot):
    Study.objects.filter(pk=prolific_study.pk).update(max_participants=1)
    first = make_bot(prolific_study)
    first.join(**ids(PID))
    first.consent(screen_0="Yes")
    second = make_bot(prolific_study)
    assert b"This study is full" in second.enter(**ids("a" * 24)).content
    declined = make_bot(prolific_study)  # saying no takes no place
    declined.enter(**ids("b" * 24))
    declined.client.post(declined.url("consent"), {"decline": "1"})
    Participant.objects.filter(external_key__endswith=PID).update(
        consented_at=timezone.now() - timedelta(minutes=31))
    second.enter(**ids("a" * 24))
    second.consent(screen_0="Yes")
    assert Participant.objects.filter(consented_at__isnull=False).count() == 2
    late = first.answer({"trial": "1"})
    assert late.status_code == 410 and b"time for this study has run out" in late.content
    assert Participant.objects.get(external_key__endswith=PID).outcome == "timed_out"
    assert b"run out" in first.enter(**ids(PID)).content


def test_a_generic_platform_sends_people_to_its_completion_url(media_root, clips, make_bot):
    crowd = {"platform": "generic", "id_param": "participantId", "extra_params": ["projectId"],
             "completion_url_template": "https://connect.example/complete?code={code}&id={id}",
             "codes": {"completed": "DONE1234"}}
    study = make_study("ranking", clips, slug="connect", crowd=crowd)
    bot = make_bot(study)
    bot.join(participantId="w-42", projectId="p7", PROLIFIC_PID="ignored")
    assert Participant.objects.get().external_ids == {"participantId": "w-42", "projectId": "p7"}
    done = bot.finish().content.decode()
    url = "https://connect.example/complete?code=DONE1234&amp;id=w-42"
    assert f'content="3;url={url}"' in done and f'href="{url}"' in done


def test_a_study_without_a_platform_keeps_a_random_code_and_its_link(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join(PROLIFIC_PID="anyone")
    page = bot.finish().content.decode()
    code = bot.participant().completion_code
    assert re.fullmatch(r"[0-9A-F]{8}", code) and code in page
    assert 'http-equiv="refresh"' not in page  # a link, not a redirect, as before


# The server decides whether clips were watched.


@pytest.fixture
def watching(settings):
    settings.STUDY_WATCH_TIME_FACTOR = 1.0


def test_an_answer_needs_every_clip_fetched_whole_and_its_time_played(ranking_study, make_bot,
                                                                     watching):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    data = bot.answer_data(trial)
    Trial.objects.filter(pk=trial.pk).update(shown_at=None)
    never_opened = bot.answer(data)
    assert never_opened.status_code == 400 and b"never opened" in never_opened.content
    bot.trial_page(watch=False)
    unfetched = bot.answer(data)
    assert unfetched.status_code == 400
    assert b"has not been loaded to its end yet" in unfetched.content
    items = list(trial.items.order_by("position"))
    first = bot.client.get(items[0].clip_url(), HTTP_RANGE="bytes=0-99")
    b"".join(first.streaming_content)  # only the start of the file
    assert not TrialItem.objects.filter(pk=items[0].pk, fetched_at__isnull=False).exists()
    rest = bot.client.get(items[0].clip_url(), HTTP_RANGE="bytes=100-")
    b"".join(rest.streaming_content)  # the rest: now it has all been sent
    assert TrialItem.objects.filter(pk=items[0].pk, fetched_at__isnull=False).exists()
    bot.watch(trial)
    if (timezone.now() - Trial.objects.get(pk=trial.pk).shown_at).total_seconds() < 0.3:
        too_soon = bot.answer(data)
        assert too_soon.status_code == 400 and b"before its clips" in too_soon.content
    time.sleep(items[0].stimulus.duration)
    assert bot.answer(data).status_code == 302


@pytest.mark.django_db(transaction=True)
def test_bots_that_do_not_fetch_the_clips_are_refused(ranking_study, live_server, watching):
    with pytest.raises(CommandError, match="did not finish"):
        call_command("simulate_participants", study=ranking_study.slug, n=2, url=live_server.url,
                     no_watch=True, stdout=StringIO(), stderr=StringIO())
    assert not Trial.objects.filter(answered_at__isnull=False).exists()


def test_the_pages_event_log_is_stored_and_exported(ranking_study, make_bot):
    bot = make_bot(ranking_study)
    bot.join()
    trial = bot.participant().current_trial()
    bot.trial_page()
    events = '[[120,"play",0],[130,"play",1],[900,"hidden",null],[1500,"ended",0]]'
    assert bot.answer(bot.answer_data(trial) | {"events": events}).status_code == 302
    assert Trial.objects.get(pk=trial.pk).events[2] == [900, "hidden", None]
    table = responses_frame(ranking_study)
    assert table["page_hidden"].tolist() == [1, 1, 1] and table["n_events"].tolist() == [4] * 3
    bot.trial_page()
    second = bot.participant().current_trial()
    forged = bot.answer(bot.answer_data(second) | {"events": '[[1,"teleport",0]]'})
    assert forged.status_code == 400 and b"record of playback is malformed" in forged.content


def test_every_participant_sees_the_real_share_and_stimuli_stay_balanced(media_root, make_bot):
    from collections import Counter

    study = Study.objects.create_study("fake_or_real", "share", "Share",
                                       trials_per_participant=12)
    make_stimuli(study, actions=("walk", "wave", "jump"), per_cell=2)
    for _ in range(10):
        make_bot(study).join()
    for person in Participant.objects.all():
        sources = list(TrialItem.objects.filter(trial__participant=person)
                       .values_list("stimulus__source", flat=True))
        assert abs(sources.count("real") - 12 / len(SOURCES)) <= 1, sources
    counts = Counter({s.pk: 0 for s in study.stimuli.all()})
    counts.update(TrialItem.objects.values_list("stimulus", flat=True))
    assert max(counts.values()) - min(counts.values()) <= 2, counts


def test_the_base_platform_knows_no_platform_and_each_platform_its_own_settings():
    import inspect

    from studyapp.crowd import platform as crowd

    base = inspect.getsource(crowd.Platform)
    assert not re.search("prolific|PROLIFIC|SESSION_ID|STUDY_ID", base)
    assert crowd.Platform.id_params == () and crowd.Platform.extra_params == ()
    assert set(crowd.list_platforms()) >= {"none", "generic", "prolific"}
    with pytest.raises(ValueError, match="crowd.prolific_study_id: unknown setting"):
        make_platform({"platform": "generic", "id_param": "workerId",
                       "prolific_study_id": "a" * 24})
    generic = make_platform({"platform": "generic", "id_param": "workerId"})
    assert generic.client() is None and make_platform({}).client() is None


def test_entry_links_carry_the_platforms_own_parameters():
    generic = make_platform({"platform": "generic", "id_param": "workerId"})
    assert generic.entry_params(None, "w1") == [("workerId", "w1")]
    prolific = make_platform({"platform": "prolific", "codes": {"completed": "C1"},
                              "prolific_study_id": "b" * 24})
    params = dict(prolific.entry_params(None, "a" * 24))
    assert params["PROLIFIC_PID"] == "a" * 24 and params["STUDY_ID"] == "b" * 24
    assert re.fullmatch("[0-9a-f]{24}", params["SESSION_ID"])
