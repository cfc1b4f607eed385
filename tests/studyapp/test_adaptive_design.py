"""Adaptive designs in the app: main trials planned from the stored distribution, balanced
until one is stored, its recomputation started in the background, its settings checked."""

import random
from collections import Counter

import pytest
from django.core.exceptions import ValidationError

from studyapp.participation import adaptive
from studyapp.survey.models import Study
from studyapp.survey.study_types import list_study_types
from tests.studyapp.conftest import SOURCES, make_stimuli

pytestmark = pytest.mark.django_db

ADAPTIVE = [name for name in list_study_types() if adaptive.supports(name)]
PAIRS = [name for name in ADAPTIVE if adaptive.model(name) == "pairs"]
SETS = [name for name in ADAPTIVE if adaptive.model(name) == "sets"]
OTHERS = [name for name in list_study_types() if not adaptive.supports(name)]


def adaptive_study(study_type, clips_per_trial=2, **settings):
    study = Study.objects.create_study(study_type, "adaptive", "Adaptive", design="adaptive",
                                       adaptive=settings, trials_per_participant=6,
                                       clips_per_trial=clips_per_trial)
    make_stimuli(study, per_cell=2)
    return study


def test_some_types_offer_it_and_the_others_refuse_it():
    assert PAIRS and SETS and OTHERS
    assert "worth model" in adaptive.check("adaptive", {}, OTHERS[0])
    assert adaptive.check("adaptive", {"every": 20, "target": "top_two"}, ADAPTIVE[0]) is None
    assert "every" in adaptive.check("adaptive", {"every": 0}, ADAPTIVE[0])
    assert "not a setting" in adaptive.check("adaptive", {"speed": 1}, ADAPTIVE[0])
    assert "not one of" in adaptive.check("greedy", {}, ADAPTIVE[0])
    assert adaptive.check("adaptive", {"batch": 50}, PAIRS[0]) is None
    assert "pairs of sources only" in adaptive.check("adaptive", {"batch": 50}, SETS[0])
    with pytest.raises(ValidationError, match="worth model"):
        Study.objects.create_study(OTHERS[0], "other", "Other", design="adaptive")


def test_pairs_aimed_at_the_order_are_planned_in_batches_by_default():
    def batch(study_type, **given):
        return adaptive.settings(Study(study_type=study_type, adaptive=given))["batch"]

    assert batch(PAIRS[0]) == 50 and batch(PAIRS[0], every=20) == 20  # a batch per look
    assert batch(PAIRS[0], every=20, batch=0) == 0 and batch(PAIRS[0], batch=7) == 7
    assert batch(PAIRS[0], target="top_two") == 0
    assert batch(PAIRS[0], target={"versus": SOURCES[0]}) == 0
    assert batch(SETS[0]) == 0  # sets are never batched
    arena = Study(study_type=PAIRS[0], adaptive={}, arena={"min_votes": 30})
    assert adaptive.settings(arena)["batch"] == 0  # as the arena's benchmark ran


@pytest.mark.parametrize("study_type", PAIRS)
def test_balanced_until_a_distribution_is_stored_and_a_recompute_is_asked_for(
        study_type, monkeypatch, django_capture_on_commit_callbacks):
    started = []
    monkeypatch.setattr(adaptive, "run_job", lambda kind, **params: started.append(params))
    study = adaptive_study(study_type)
    with django_capture_on_commit_callbacks(execute=True):
        plans = study.kind.plan_trials(study, random.Random(0))
    assert len(plans) == 6 and all(len(p.stimuli) == 2 for p in plans)
    assert started == [{"name": "adaptive_design", "args": [study.slug]}]
    assert study.sampling["requested"] == 0 and "pairs" not in study.sampling
    # No new answers: no second request.
    with django_capture_on_commit_callbacks(execute=True):
        study.kind.plan_trials(study, random.Random(1))
    assert len(started) == 1


@pytest.mark.parametrize("study_type", PAIRS)
def test_trials_follow_the_stored_distribution_under_the_constraints(study_type):
    study = adaptive_study(study_type, min_showings=0)
    names = sorted(SOURCES)
    study.sampling = {"sources": names, "pairs": [[0, 1], [0, 2], [1, 2]], "p": [1.0, 0.0, 0.0],
                      "answers": 0}
    study.save()
    plans = study.kind.plan_trials(study, random.Random(0))
    assert len(plans) == 6
    shown = [tuple(s.source for s in plan.stimuli) for plan in plans]
    assert all(set(pair) == {names[0], names[1]} for pair in shown)
    assert all(plan.stimuli[0].action == plan.stimuli[1].action for plan in plans)
    # No pair of clips twice for one participant; each source as often left as right.
    keys = [frozenset(s.pk for s in plan.stimuli) for plan in plans]
    assert len(set(keys)) == len(keys)
    left = Counter(pair[0] for pair in shown)
    assert left[names[0]] == left[names[1]] == 3


@pytest.mark.parametrize("study_type", PAIRS)
def test_every_clip_gets_its_minimum_before_the_distribution_decides(study_type):
    study = adaptive_study(study_type, min_showings=1)
    names = sorted(SOURCES)
    study.sampling = {"sources": names, "pairs": [[0, 1], [0, 2], [1, 2]], "p": [1.0, 0.0, 0.0],
                      "answers": 0}
    study.save()
    plans = study.kind.plan_trials(study, random.Random(0))
    assert {s.source for plan in plans for s in plan.stimuli} == set(SOURCES)


@pytest.mark.parametrize("study_type", PAIRS)
def test_the_command_stores_a_distribution_over_the_studys_sources(study_type):
    from django.core.management import call_command

    study = adaptive_study(study_type)
    call_command("adaptive_design", study.slug, stdout=open("/dev/null", "w"))
    study.refresh_from_db()
    assert study.sampling["sources"] == sorted(SOURCES)
    assert len(study.sampling["pairs"]) == 3 and sum(study.sampling["p"]) == pytest.approx(1)
    assert study.sampling["answers"] == 0
    plans = study.kind.plan_trials(study, random.Random(0))
    assert len(plans) == 6


def test_the_config_takes_the_design_and_checks_it():
    from studyapp.stimuli.config import ConfigError, _study

    _, options, _, _ = _study({"type": ADAPTIVE[0], "design": "adaptive",
                               "adaptive": {"every": 20, "min_showings": 3}})
    assert options["design"] == "adaptive" and options["adaptive"]["every"] == 20
    with pytest.raises(ConfigError, match="worth model"):
        _study({"type": OTHERS[0], "design": "adaptive"})
    with pytest.raises(ConfigError, match="adaptive.target"):
        _study({"type": ADAPTIVE[0], "design": "adaptive", "adaptive": {"target": "best"}})


@pytest.mark.parametrize("study_type", PAIRS)
def test_answers_through_the_pages_reach_the_posterior(study_type, media_root, clips,
                                                       extra_clips, make_bot):
    from django.core.management import call_command

    from tests.studyapp.conftest import make_study

    study = make_study(study_type, clips, extra_clips, design="adaptive",
                       adaptive={"every": 2}, trials_per_participant=2)
    for _ in range(3):
        bot = make_bot(study)
        bot.join()
        bot.finish()
    # Bots answer at once; the analysis's exclusions (which the posterior applies too)
    # would leave out answers faster than the clips.
    from studyapp.survey.models import Trial

    Trial.objects.update(time_ms=60_000)
    call_command("adaptive_design", study.slug, stdout=open("/dev/null", "w"))
    study.refresh_from_db()
    assert study.sampling["answers"] == 6
    assert 0 < study.sampling["comparisons"] <= 6
    assert len(study.sampling["worth"]) == len(study.sampling["sources"])


@pytest.mark.parametrize("study_type", PAIRS)
def test_a_versus_target_aims_at_that_source(study_type):
    from studyapp.results.adaptive import recompute

    study = adaptive_study(study_type, target={"versus": SOURCES[0]})
    sampling = recompute(study)
    names = sampling["sources"]
    at = {tuple(names[i] for i in pair): p for pair, p in zip(sampling["pairs"], sampling["p"])}
    mine = [p for pair, p in at.items() if SOURCES[0] in pair]
    others = [p for pair, p in at.items() if SOURCES[0] not in pair]
    assert min(mine) > max(others) and "note" not in sampling
    study.adaptive = {"target": {"versus": SOURCES[0]}, "batch": 30}
    batched = recompute(study)
    at = {tuple(names[i] for i in pair): p for pair, p in zip(batched["pairs"], batched["p"])}
    assert sum(p for pair, p in at.items() if SOURCES[0] in pair) > 0.75  # balanced: 2/3
    study.adaptive = {"target": {"versus": "nobody"}}
    assert "aimed at the order" in recompute(study)["note"]


FIVE = ("s1", "s2", "s3", "s4", "s5")


def set_study(study_type, **settings):
    study = Study.objects.create_study(study_type, "adaptive-sets", "Adaptive sets",
                                       design="adaptive", adaptive=settings,
                                       trials_per_participant=6, clips_per_trial=3)
    make_stimuli(study, sources=FIVE, per_cell=2)
    return study


@pytest.mark.parametrize("study_type", SETS)
def test_sets_follow_the_stored_distribution_under_the_constraints(study_type):
    study = set_study(study_type, min_showings=0)
    study.sampling = {"sources": list(FIVE), "sets": [[0, 1, 2], [2, 3, 4]], "p": [1.0, 0.0],
                      "size": 3, "answers": 0}
    study.save()
    plans = study.kind.plan_trials(study, random.Random(0))
    assert len(plans) == 6
    shown = [tuple(s.source for s in plan.stimuli) for plan in plans]
    assert all(sorted(trial) == ["s1", "s2", "s3"] for trial in shown)
    assert all(len({s.action for s in plan.stimuli}) == 1 for plan in plans)
    keys = [frozenset(s.pk for s in plan.stimuli) for plan in plans]
    assert len(set(keys)) == len(keys)
    # Each source twice in each of the three seats over six trials.
    seats = Counter((source, seat) for trial in shown for seat, source in enumerate(trial))
    assert set(seats.values()) == {2}


@pytest.mark.parametrize("study_type", SETS)
def test_the_command_stores_a_distribution_over_sets(study_type):
    from django.core.management import call_command
    from io import StringIO

    study = set_study(study_type)
    out = StringIO()
    call_command("adaptive_design", study.slug, stdout=out)
    study.refresh_from_db()
    assert study.sampling["sources"] == list(FIVE) and study.sampling["size"] == 3
    assert len(study.sampling["sets"]) == 10 and sum(study.sampling["p"]) == pytest.approx(1)
    assert "most likely sets" in out.getvalue()
    plans = study.kind.plan_trials(study, random.Random(0))
    assert len(plans) == 6 and all(len(plan.stimuli) == 3 for plan in plans)


@pytest.mark.parametrize("study_type", SETS)
def test_set_answers_through_the_pages_reach_the_posterior(study_type, media_root, clips,
                                                           extra_clips, make_bot):
    from django.core.management import call_command

    from studyapp.survey.models import Trial
    from tests.studyapp.conftest import make_study

    study = make_study(study_type, clips, extra_clips, design="adaptive",
                       adaptive={"every": 2}, trials_per_participant=2, clips_per_trial=2)
    for _ in range(3):
        bot = make_bot(study)
        bot.join()
        bot.finish()
    Trial.objects.update(time_ms=60_000)
    call_command("adaptive_design", study.slug, stdout=open("/dev/null", "w"))
    study.refresh_from_db()
    assert study.sampling["answers"] == 6 and study.sampling["size"] == 2
    assert 0 < study.sampling["comparisons"] <= 6


# Stopping rules


def test_the_config_and_the_study_check_the_stopping_rule():
    from studyapp.stimuli.config import ConfigError, _study

    _, options, _, _ = _study({"type": PAIRS[0], "design": "adaptive",
                               "stop_when": {"interval_width": 0.6, "judgements": 3000}})
    assert options["stop_when"] == {"interval_width": 0.6, "judgements": 3000}
    _study({"type": OTHERS[0], "stop_when": {"judgements": 500}})  # a budget fits every type
    for rule, message in [({"interval_width": 0}, "above 0"),
                          ({"rank_certainty": 1.2}, r"\[0.5, 1\)"),
                          ({"judgements": 2.5}, "whole number"),
                          ({"width": 0.5}, "not a stopping rule"),
                          ([0.5], "stop_when")]:
        with pytest.raises(ConfigError, match=message):
            _study({"type": PAIRS[0], "stop_when": rule})
    with pytest.raises(ConfigError, match="stop it by judgements"):
        _study({"type": OTHERS[0], "stop_when": {"rank_certainty": 0.9}})
    with pytest.raises(ValidationError, match="stop_when"):
        Study.objects.create_study(PAIRS[0], "bad-stop", "Bad", stop_when={"interval_width": -1})


@pytest.mark.parametrize("kind", OTHERS)
def test_a_budget_is_checked_for_types_that_plan_their_own_trials(kind, media_root, clips,
                                                                  extra_clips, make_bot,
                                                                  monkeypatch,
                                                                  django_capture_on_commit_callbacks):
    """Types without an adaptive design, some with their own main-trial planning, still ask
    for the stopping rule's check once their budget of judgements is reached."""
    from tests.studyapp.conftest import make_study

    started = []
    monkeypatch.setattr(adaptive, "run_job", lambda kind, **params: started.append(params))
    study = make_study(kind, clips, extra_clips, stop_when={"judgements": 1},
                       trials_per_participant=1)
    with django_capture_on_commit_callbacks(execute=True):
        first = make_bot(study)
        first.join()
    first.finish()
    assert len(started) == 1  # the first start asks for the first check
    with django_capture_on_commit_callbacks(execute=True):
        make_bot(study).join()
    # The budget was reached since: asked again, although fewer than `every` answers.
    assert len(started) == 2 and started[-1]["name"] == "adaptive_design"


@pytest.mark.parametrize("design", ["adaptive", "balanced"])
def test_a_budget_stops_the_study_and_closes_its_places(design, media_root, clips, extra_clips,
                                                        make_bot, monkeypatch,
                                                        django_capture_on_commit_callbacks):
    from django.core.management import call_command

    from studyapp.participation.adaptive import answered_main
    from studyapp.survey.models import Trial
    from tests.studyapp.conftest import make_study

    started = []
    monkeypatch.setattr(adaptive, "run_job", lambda kind, **params: started.append(params))
    study = make_study(PAIRS[0], clips, extra_clips, design=design, adaptive={"every": 50},
                       stop_when={"judgements": 4}, trials_per_participant=2)
    for _ in range(3):
        with django_capture_on_commit_callbacks(execute=True):
            bot = make_bot(study)
            bot.join()
        bot.finish()
    # The third participant's start found the budget reached and asked for the check,
    # although fewer than ``every`` answers came in since the last.
    assert len(started) == 2
    Trial.objects.update(time_ms=60_000)
    call_command("adaptive_design", study.slug, stdout=open("/dev/null", "w"))
    study.refresh_from_db()
    assert study.status == Study.Status.CLOSED
    assert study.stopped["rule"] == "judgements" and study.stopped["judgements"] == answered_main(study) == 6
    assert study.stopped["design"] == design and study.stopped["platform"] == ""
    late = make_bot(study)
    assert "This study is not open" in late.enter().content.decode()
    # The report says how the study chose its trials and stopped.
    out = media_root / "report"
    call_command("analyze", study=study.slug, out=str(out), bootstrap=20, no_audit=True,
                 stdout=open("/dev/null", "w"))
    report = (out / "report.html").read_text()
    assert "The study stopped by its stopping rule when its budget of 4 answered main" in report
    assert ("The design was adaptive" in report) == (design == "adaptive")
    # The settings that ran, the default batch of a pairs study aimed at the order included.
    assert ("planned in batches of 50 comparisons" in report) == (design == "adaptive")


def test_a_met_interval_width_stops_the_study_on_prolific(monkeypatch):
    from io import StringIO

    from django.core.management import call_command

    from tests.studyapp.prolific_fake import FakeProlific

    with FakeProlific(token="stop-token") as fake:
        monkeypatch.setenv("PROLIFIC_TOKEN", "stop-token")
        monkeypatch.setenv("PROLIFIC_API_URL", fake.url)
        study = Study.objects.create_study(PAIRS[0], "stop-prolific", "Movement study",
                                           design="adaptive", max_participants=20,
                                           stop_when={"interval_width": 100.0})
        make_stimuli(study, per_cell=2)
        call_command("prolific", "create", "--study", study.slug, "--base-url",
                     "https://study.example", stdout=StringIO(), stderr=StringIO())
        call_command("prolific", "publish", "--study", study.slug, stdout=StringIO())
        study.refresh_from_db()
        prolific_id = study.crowd["prolific_study_id"]
        assert fake.studies[prolific_id]["status"] == "ACTIVE"
        out = StringIO()
        # No answers yet: the prior's interval (wider than 16) is narrower than 100.
        call_command("adaptive_design", study.slug, stdout=out)
        study.refresh_from_db()
        assert fake.studies[prolific_id]["status"] == "AWAITING REVIEW"
        assert study.status == Study.Status.CLOSED
        assert study.stopped["rule"] == "interval_width" and study.stopped["width"] <= 100
        assert "STOP sent" in study.stopped["platform"] and "stopped by interval_width" in out.getvalue()
        # Stopped once: a second check sends nothing more.
        call_command("adaptive_design", study.slug, stdout=StringIO())
        sent = fake.requests("POST", f"/api/v1/studies/{prolific_id}/transition/")
        assert [r["body"]["action"] for r in sent] == ["PUBLISH", "STOP"]


def test_the_example_config_is_adaptive_with_a_stopping_rule():
    from pathlib import Path

    from studyapp.stimuli.config import load_config

    config = load_config(Path(__file__).resolve().parents[2] / "studies" / "adaptive_pairwise.yaml")
    assert config.study_options["design"] == "adaptive"
    assert config.study_options["stop_when"] == {"interval_width": 1.5, "judgements": 600}
    assert adaptive.supports(config.study_type)


def test_a_budget_is_checked_for_a_type_without_a_worth_model():
    from studyapp.results.adaptive import recompute

    study = Study.objects.create_study(OTHERS[0], "budget-only", "Budget", stop_when={"judgements": 1})
    make_stimuli(study, per_cell=1)
    sampling = recompute(study)
    assert sampling["stop"]["met"] == "" and sampling["stop"]["judgements"] == 0
    assert "pairs" not in sampling and not study.stopped


def test_a_failed_stop_on_prolific_says_how_to_retry(monkeypatch):
    from studyapp.crowd.platform import make_platform

    monkeypatch.delenv("PROLIFIC_TOKEN", raising=False)
    platform = make_platform({"platform": "prolific", "codes": {"completed": "C1A2B3C4"},
                              "prolific_study_id": "64f0c0ffee0000000000beef"})
    said = platform.stop_recruiting(Study(slug="s"))
    assert "STOP failed" in said and "PROLIFIC_TOKEN" in said and "prolific stop --study s" in said
    assert "nothing sent" in make_platform({"platform": "prolific", "codes": {
        "completed": "C1A2B3C4"}}).stop_recruiting(Study(slug="s"))


@pytest.mark.parametrize("study_type", SETS)
def test_the_stopping_rule_of_sets_counts_clips_and_participants(study_type, media_root, clips,
                                                                 extra_clips, make_bot, monkeypatch):
    """Best of k and ranking: the choices name their clips and participants, so the
    rule reads the interval that counts clips as random, as for pairs."""
    import itertools

    from django.core.management import call_command

    from analysis.registry import get_analysis
    from studyapp.results.adaptive import fit, main_rows
    from studyapp.survey.models import Trial
    from tests.studyapp.conftest import make_study

    study = make_study(study_type, clips, extra_clips, design="adaptive",
                       adaptive={"every": 2}, trials_per_participant=3, clips_per_trial=3,
                       stop_when={"interval_width": 0.01})
    seeds = itertools.count(1)  # participants' plans seeded: the same trials every run
    monkeypatch.setattr("studyapp.survey.models.participation.secrets.randbits", lambda bits: next(seeds))
    for _ in range(4):
        bot = make_bot(study)
        bot.join()
        bot.finish()
    Trial.objects.update(time_ms=60_000)
    call_command("adaptive_design", study.slug, stdout=open("/dev/null", "w"))
    study.refresh_from_db()
    stop = study.sampling["stop"]
    assert stop["interval"] == "clips" and stop["met"] == "" and study.status != Study.Status.CLOSED
    main = main_rows(study)
    choices = get_analysis(study_type).worth_choices(main)
    assert all(len(c) == len(s) for c, s in zip(choices["among_clips"], choices["among"]))
    _, _, spread = fit(study, study.sampling["sources"], main)
    assert spread.steady is not None and spread.df >= 1
