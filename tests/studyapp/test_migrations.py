"""Existing studies and their answers survive the change to roles, item tokens and answers
per criterion: a study made on the old schema (0002) reads back after migrating."""

import pytest
from django.db import connection
from django.db.migrations.executor import MigrationExecutor
from django.utils import timezone

from studyapp.results.export import participants_frame, responses_frame

OLD = [("survey", "0002_build_job")]


def migrate(targets):
    executor = MigrationExecutor(connection)
    executor.loader.build_graph()
    executor.migrate(targets)
    return executor.loader.project_state(targets).apps


@pytest.mark.django_db(transaction=True)
def test_a_study_on_the_old_schema_reads_back_after_migrating():
    latest = MigrationExecutor(connection).loader.graph.leaf_nodes("survey")
    old = migrate(OLD)
    Study, Stimulus = old.get_model("survey", "Study"), old.get_model("survey", "Stimulus")
    Participant, Trial = old.get_model("survey", "Participant"), old.get_model("survey", "Trial")
    TrialItem = old.get_model("survey", "TrialItem")
    now = timezone.now()

    pairs = Study.objects.create(slug="old-pairs", title="Old", study_type="pairwise",
                                 clips_per_trial=2, allow_ties=True)
    rating = Study.objects.create(slug="old-rating", title="Old", study_type="rating_reference",
                                  clips_per_trial=2, catch_trials=1)

    def stimulus(study, source, **flags):
        return Stimulus.objects.create(study=study, action="walk", source=source,
                                       video=f"stimuli/{study.pk}{source}.mp4", duration=1.0,
                                       video_hash=f"{study.pk:02d}{source}" + "0" * 20, **flags)

    left, right = stimulus(pairs, "real"), stimulus(pairs, "a2m")
    person = Participant.objects.create(study=pairs, seed=1, external_key="PROLIFIC_PID:p1",
                                        external_ids={"PROLIFIC_PID": "p1"},
                                        consented_at=now, completed_at=now, completion_code="X1")
    trial = Trial.objects.create(participant=person, index=0, action="walk", choice="both_good",
                                 shown_at=now, answered_at=now, time_ms=2000)
    TrialItem.objects.create(trial=trial, stimulus=left, position=0, plays=1)
    TrialItem.objects.create(trial=trial, stimulus=right, position=1, plays=1)

    a, b = stimulus(rating, "real"), stimulus(rating, "cond_gru")
    reference = stimulus(rating, "real_ref", is_reference=True)
    broken = stimulus(rating, "broken", is_catch=True)
    rater = Participant.objects.create(study=rating, seed=2, consented_at=now, completed_at=now)
    shown = Trial.objects.create(participant=rater, index=0, action="walk", reference=reference,
                                 shown_at=now, answered_at=now, time_ms=3000)
    TrialItem.objects.create(trial=shown, stimulus=a, position=0, rating=4, plays=1)
    TrialItem.objects.create(trial=shown, stimulus=b, position=1, rating=2, plays=1)
    catch = Trial.objects.create(participant=rater, index=1, action="walk", kind="catch",
                                 reference=reference, catch_passed=False, shown_at=now,
                                 answered_at=now, time_ms=3000)
    TrialItem.objects.create(trial=catch, stimulus=broken, position=0, rating=5, plays=1)
    TrialItem.objects.create(trial=catch, stimulus=a, position=1, rating=4, plays=1)

    migrate(latest)
    from studyapp.survey.models import Stimulus as NowStimulus
    from studyapp.survey.models import Study as NowStudy
    from studyapp.survey.models import TrialItem as NowItem

    pairs, rating = NowStudy.objects.get(slug="old-pairs"), NowStudy.objects.get(slug="old-rating")
    assert pairs.options == {"allow_ties": True} and pairs.option("allow_ties") is True
    roles = dict(NowStimulus.objects.filter(study=rating).values_list("source", "role"))
    assert roles == {"real": "judged", "cond_gru": "judged", "real_ref": "reference",
                     "broken": "catch"}
    tokens = list(NowItem.objects.values_list("token", flat=True))
    assert len(tokens) == len(set(tokens)) == 8  # 6 items and 2 references, each its own
    assert NowItem.objects.filter(role="reference").count() == 2

    table = responses_frame(pairs)
    assert table["choice"].tolist() == ["both_good", "both_good"]
    assert table["criterion"].tolist() == ["preference", "preference"]
    assert table["PROLIFIC_PID"].tolist() == ["p1", "p1"]
    rated = responses_frame(rating)
    assert rated.loc[rated["trial_kind"] == "main", "rating"].tolist() == [4, 2]
    assert rated.loc[rated["is_catch"], "rating"].tolist() == [5]
    assert len(rated) == 4  # references were never judgements, and still are not
    assert participants_frame(rating)["outcome"].tolist() == ["failed_attention"]
    assert participants_frame(pairs)["outcome"].tolist() == ["completed"]


@pytest.mark.django_db(transaction=True)
def test_a_study_with_the_in_page_player_reads_back_after_its_choices_go():
    """0009 drops Study.player's choices (a style declares its figure): the value stays."""
    latest = MigrationExecutor(connection).loader.graph.leaf_nodes("survey")
    old = migrate([("survey", "0008_stimulus_checkpoint")])
    Study, Stimulus = old.get_model("survey", "Study"), old.get_model("survey", "Stimulus")
    Participant, Trial = old.get_model("survey", "Participant"), old.get_model("survey", "Trial")
    TrialItem = old.get_model("survey", "TrialItem")
    now = timezone.now()
    study = Study.objects.create(slug="old-player", title="Old", study_type="pairwise",
                                 clips_per_trial=2, player="body")
    clips = [Stimulus.objects.create(study=study, action="walk", source=source,
                                     video=f"stimuli/{source}.mp4", duration=1.0,
                                     video_hash=source + "0" * 24, motion=f"payloads/{source}.motion")
             for source in ("real", "a2m")]
    person = Participant.objects.create(study=study, seed=1, consented_at=now, completed_at=now)
    trial = Trial.objects.create(participant=person, index=0, action="walk", shown_at=now,
                                 answered_at=now, time_ms=2000, answers={"preference": "left"})
    for position, clip in enumerate(clips):
        TrialItem.objects.create(trial=trial, stimulus=clip, position=position, plays=1,
                                 token=f"tok{position}")

    migrate(latest)
    from studyapp.survey.models import Study as NowStudy

    assert NowStudy.objects.get(slug="old-player").player == "body"
    table = responses_frame(NowStudy.objects.get(slug="old-player"))
    assert table["choice"].tolist() == ["left", "left"]
    assert table["source"].tolist() == ["real", "a2m"]


@pytest.mark.django_db
def test_the_models_match_the_migrations():
    """The models live in rooms of one concern but keep the app label and tables they had:
    no migration is missing, so an existing database is read as it is."""
    from io import StringIO

    from django.core.management import call_command

    out = StringIO()
    call_command("makemigrations", "--check", "--dry-run", stdout=out)
    assert "No changes detected" in out.getvalue()
