"""simulate_participants (bots over real HTTP against the live server) and studies."""

import json
import math
from io import StringIO

import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from analysis.registry import get_analysis
from studyapp.participation import bots
from studyapp.results.export import participants_frame, responses_frame
from studyapp.survey.models import Participant, Study, TrialItem
from studyapp.survey.study_types import list_study_types
from tests.studyapp.conftest import make_study

pytestmark = pytest.mark.django_db(transaction=True)



@pytest.fixture
def study_of(transactional_db, media_root, clips, extra_clips):
    return lambda study_type, **fields: make_study(study_type, clips, extra_clips, **fields)


def simulate_run(study, url, **options) -> str:
    out = StringIO()
    options.setdefault("pace", 0)
    call_command("simulate_participants", study=study.slug, url=url, stdout=out, **options)
    return out.getvalue()


@pytest.mark.parametrize("study_type", list_study_types())
def test_bots_take_every_type_through_the_real_pages(study_of, live_server, study_type):
    study = study_of(
        study_type, catch=True, practice=True, repeat_trials=1, ask_demographics=True
    )
    out = simulate_run(
        study, live_server.url, n=2, policy="bt", seed=3, strengths="real=8,a2m=2,cond_gru=1"
    )
    assert "2 of 2 simulated participants completed" in out
    people = list(Participant.objects.filter(study=study))
    assert len(people) == 2 and all(p.completed_at and p.completion_code in out for p in people)
    assert all(p.demographics is not None for p in people)
    ids = {p.external_ids["PROLIFIC_PID"] for p in people}
    assert ids == {bots.person_id(3, 1), bots.person_id(3, 2)}
    assert not TrialItem.objects.exclude(plays=1).exists()  # every clip reported played once
    assert not TrialItem.objects.filter(required=True, fetched_at=None).exists()  # fetched
    table = responses_frame(study)
    answer = get_analysis(study_type).answer
    assert table[answer].notna().all() and len(table) > 0
    assert set(table["trial_kind"]) == {"main", "catch", "repeat"}
    assert table.loc[table["trial_kind"] == "catch", "catch_passed"].notna().all()
    assert len(participants_frame(study)) == 2


def test_bots_get_the_next_trial_in_the_answers_response(study_of, live_server, monkeypatch):
    """Bots post the trial form as a browser does (its ``next`` field too): no answer is
    followed by a redirect to the next trial, only the last one by a redirect onwards."""
    import urllib.request

    study = study_of("ranking", trials_per_participant=3)
    redirects = []
    follow = urllib.request.HTTPRedirectHandler.redirect_request

    def counted(self, req, fp, code, msg, headers, newurl):
        redirects.append((req.full_url.rsplit("/", 2)[-2], newurl.rsplit("/", 2)[-2]))
        return follow(self, req, fp, code, msg, headers, newurl)

    monkeypatch.setattr(urllib.request.HTTPRedirectHandler, "redirect_request", counted)
    out = simulate_run(study, live_server.url, n=1, policy="random", seed=6)
    assert "1 of 1 simulated participants completed" in out
    assert ("trial", "trial") not in redirects
    assert [r for r in redirects if r[0] == "trial"] == [("trial", "done")]


def test_prefer_real_bots_answer_by_the_source_from_the_database(study_of, live_server):
    study = study_of("fake_or_real", catch=True)
    simulate_run(study, live_server.url, n=2, policy="prefer-real", seed=1)
    table = responses_frame(study)
    expected = table["source"].eq("real")
    assert table["judged_real"].astype(bool).tolist() == expected.tolist()
    assert table.loc[table["is_catch"], "catch_passed"].all()
    # Bots are marked (by the User-Agent they send) in both tables.
    assert table["simulated"].all() and participants_frame(study)["simulated"].all()


def test_the_bots_know_sources_only_through_the_database(study_of, live_server, monkeypatch):
    study = study_of("fake_or_real")
    real = bots.item_info

    def all_real(tokens):
        return {token: ("real", *rest) for token, (_, *rest) in real(tokens).items()}

    monkeypatch.setattr(bots, "item_info", all_real)
    simulate_run(study, live_server.url, n=1, policy="prefer-real", seed=2)
    assert responses_frame(study)["judged_real"].all()  # every clip "real", as told


def test_bradley_terry_bots_follow_their_strengths(study_of, live_server):
    ranking = study_of("ranking")
    pairwise = study_of("pairwise", slug="pairs")
    strengths = "real=1000,a2m=1,cond_gru=0.001"
    for study in (ranking, pairwise):
        simulate_run(study, live_server.url, n=3, policy="bt", seed=5, strengths=strengths)
    ranks = responses_frame(ranking).groupby("source")["rank"].mean()
    assert ranks["real"] < ranks["a2m"] < ranks["cond_gru"]
    table = responses_frame(pairwise)
    picked = table["choice"].map({"left": 0, "right": 1}) == table["position"]
    wins = table.loc[picked, "source"].value_counts()
    assert wins.get("cond_gru", 0) == 0 and wins.get("real", 0) >= wins.get("a2m", 0)


def test_simulation_mistakes_are_clear(study_of, live_server):
    study = study_of("pairwise")
    with pytest.raises(CommandError, match="not a source of study-pairwise"):
        simulate_run(study, live_server.url, strengths="real=2,sa_gcn=3")
    with pytest.raises(CommandError, match="NAME=NUMBER"):
        simulate_run(study, live_server.url, strengths="real")
    Study.objects.filter(pk=study.pk).update(status="closed")
    with pytest.raises(CommandError, match="did not finish"):
        simulate_run(study, live_server.url, n=1)


def test_paced_bots_take_as_long_as_the_clips(study_of, live_server):
    study = study_of("fake_or_real", trials_per_participant=2)
    simulate_run(study, live_server.url, n=1, seed=4, pace=1.0)
    table = responses_frame(study)
    assert (table["time_ms"] >= 1000 * table["duration"]).all()


def test_strengths_are_parsed():
    assert bots.parse_strengths("real=4, a2m=3,cond_gru=0.5") == {
        "real": 4.0, "a2m": 3.0, "cond_gru": 0.5
    }
    assert bots.parse_strengths("") == {}
    with pytest.raises(ValueError, match="positive"):
        bots.parse_strengths("real=0")


def test_studies_counts_each_outcome_once(study_of, make_bot):
    """Failing the attention checks ends a session as one outcome, not as completed and
    excluded both."""
    from studyapp.survey.models import Participant

    study = study_of("ranking")
    for _ in range(3):
        bot = make_bot(study)
        bot.join()
        bot.finish()
    failed = Participant.objects.filter(study=study).order_by("pk")[:2]
    Participant.objects.filter(pk__in=[p.pk for p in failed]).update(outcome="failed_attention")
    text = StringIO()
    call_command("studies", stdout=text)
    assert ("study-ranking (ranking, open): 3 participants (1 completed, 2 failed attention "
            "(excluded)), 18 judgements") in text.getvalue()
    out = StringIO()
    call_command("studies", json=True, stdout=out)
    row = json.loads(out.getvalue())[0]
    assert row["completed"] == 1 and row["excluded"] == 2
    assert row["outcomes"] == {"completed": 1, "failed_attention": 2}


def test_studies_lists_every_study_as_json(study_of, make_bot):
    ranking = study_of("ranking")
    study_of("rating_reference", catch=True)
    bot = make_bot(ranking)
    bot.join()
    bot.finish()
    out = StringIO()
    call_command("studies", json=True, base_url="https://study.example", stdout=out)
    rows = {row["slug"]: row for row in json.loads(out.getvalue())}
    assert set(rows) == {"study-ranking", "study-rating-reference"}
    row = rows["study-ranking"]
    assert row["type"] == "ranking" and row["status"] == "open"
    assert row["sources"] == ["a2m", "cond_gru", "real"]
    assert row["participant_url"] == "https://study.example/s/study-ranking/"
    assert row["participants"] == 1 and row["completed"] == 1
    assert row["judgements"] == 6 and row["excluded"] == 0
    assert rows["study-rating-reference"]["sources"] == ["a2m", "cond_gru", "real"]  # no extras
    text = StringIO()
    call_command("studies", stdout=text)
    assert "study-ranking (ranking, open): 1 participants" in text.getvalue()


def test_a_bots_study_reports_what_ran_and_that_it_was_simulated(study_of, live_server,
                                                                  tmp_path):
    """Ties not offered (the pairwise default): the paragraph never speaks of them; the
    study's catch trial, repeat and practice trial are described; bots are named first."""
    study = study_of("pairwise", catch=True, practice=True, repeat_trials=1)
    simulate_run(study, live_server.url, n=3, policy="bt", seed=4, strengths="real=8,a2m=2")
    call_command("analyze", study=study.slug, out=str(tmp_path), bootstrap=20, no_audit=True,
                 stdout=StringIO())
    page = (tmp_path / "report.html").read_text()
    methods = page.split("<p class='methods'>", 1)[1].split("</p>", 1)[0]
    assert methods.startswith("These data are simulated: all 3 analysed participants were bots")
    assert "class='simulated'" in page.split("<h2>", 1)[0]
    lowered = methods.lower()
    assert not any(word in lowered for word in ("both good", "both bad", "equally", " tie"))
    assert "1 catch trial per participant" in methods
    assert "showing 1 main trial per participant a second time" in lowered
    assert "a practice trial came first" in lowered
    assert (tmp_path / "supplement.pdf").read_bytes().startswith(b"%PDF")
    assert (tmp_path / "headline_sources.tex").is_file()


def test_clip_variation_is_fixed_per_clip_and_off_by_default():
    import random

    clip_a, clip_b = bots.ClipSource("real", 11), bots.ClipSource("real", 12)
    assert clip_a == "real" and hash(clip_a) == hash("real") and clip_a.stimulus == 11
    plain = bots.BradleyTerry(random.Random(0), {"real": 2.0}, ["real"])
    assert plain.strength(clip_a) == plain.strength(clip_b) == plain.strength("real") == 2.0
    varied = bots.BradleyTerry(random.Random(0), {"real": 2.0}, ["real"], clip_sd=0.3, clip_seed=7)
    again = bots.BradleyTerry(random.Random(9), {"real": 2.0}, ["real"], clip_sd=0.3, clip_seed=7)
    assert varied.strength(clip_a) == again.strength(clip_a) != varied.strength(clip_b)
    assert varied.strength(clip_a) == pytest.approx(2.0 * math.exp(bots.clip_effect(11, 0.3, 7)))
    assert varied.strength("real") == 2.0 and varied.strength(bots.CATCH) == bots.CATCH_STRENGTH
    effects = [bots.clip_effect(i, 0.3, 1) for i in range(4000)]
    assert abs(sum(effects) / len(effects)) < 0.03
    assert 0.27 < (sum(e * e for e in effects) / len(effects)) ** 0.5 < 0.33


def test_bradley_terry_bots_answer_by_the_clip_with_clip_variation(study_of, live_server):
    study = study_of("pairwise", trials_per_participant=2)
    with pytest.raises(CommandError, match="bt policy only"):
        simulate_run(study, live_server.url, n=1, clip_sd=0.3)
    simulate_run(study, live_server.url, n=2, policy="bt", seed=3, clip_sd=0.3, clip_seed=1,
                 strengths="real=2")
    assert len(responses_frame(study)) == 2 * 2 * 2
