"""The plan command: a table and a plot of power over participants x clips, and its cost."""

import pandas as pd
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from analysis.simulate import simulate


def write_responses(table, path):
    table.to_csv(path, index=False)
    return path


def test_plan_by_simulation_writes_a_table_and_a_plot(tmp_path, capsys):
    out = tmp_path / "plan"
    call_command("plan", study_type="pairwise", effect=1.5, clip_sd=0.0, trials=6,
                 participants="10,30", clips="2", studies=4, bootstrap=30, reward_per_hour=12.0,
                 out=str(out))
    printed = capsys.readouterr().out
    assert "service fee 33.3% of rewards" in printed and "Recommended:" in printed
    frame = pd.read_csv(out / "plan.csv")
    assert list(frame["participants"]) == [10, 30]
    assert {"power", "width", "minutes", "reward", "cost"} <= set(frame.columns)
    assert (out / "power.png").stat().st_size > 1000


def test_plan_from_a_pilot(tmp_path, capsys):
    pilot = write_responses(simulate("rating_standards", {"a": 0.6, "b": 0.0}, participants=24,
                                     trials=5, actions=("x",), clips_per_source=3, clip_sd=1.0,
                                     seed=2), tmp_path / "pilot.csv")
    call_command("plan", pilot=str(pilot), sources="a,b", participants="24,96", clips="3,12",
                 service_fee=0.428)
    printed = capsys.readouterr().out
    assert "from the pilot (24 participants, 3 clips per source and condition)" in printed
    assert "service fee 42.8%" in printed


def test_plan_errors_name_the_fix(tmp_path):
    with pytest.raises(CommandError, match="give --type"):
        call_command("plan")
    with pytest.raises(CommandError, match="whole numbers"):
        call_command("plan", study_type="pairwise", participants="ten")
    pilot = write_responses(simulate("rating_standards", {"a": 0.6, "b": 0.0}, participants=12,
                                     trials=3, seed=2), tmp_path / "pilot.csv")
    with pytest.raises(CommandError, match="no sources 'x' and 'y'; it has a, b"):
        call_command("plan", pilot=str(pilot), sources="x,y")


@pytest.mark.django_db
def test_plan_for_a_study_takes_its_minutes_from_the_duration_model(capsys):
    from studyapp.participation import duration
    from studyapp.survey.models import Stimulus, Study
    from tests.studyapp.conftest import make_stimuli

    # The example: the model's default study type (clips ranked per trial).
    kind = Study._meta.get_field("study_type").default
    study = Study.objects.create_study(kind, "timed", "Movement study", clips_per_trial=3,
                                       catch_trials=0)
    make_stimuli(study, actions=("walk", "wave", "jump", "sit"))
    Stimulus.objects.filter(study=study).update(duration=6.0)
    expected = study.duration().estimate / 60
    call_command("plan", study="timed", effect=1.5, clip_sd=0.0, participants="10",
                 clips="2", studies=2, bootstrap=20, reward_per_hour=12.0)
    printed = capsys.readouterr().out
    assert "estimated by study timed's duration model: 4 main trials" in printed
    assert f"Minutes per participant: {expected:.1f}," in printed
    assert f"by simulation (2 studies per design, {kind}," in printed
    # Longer clips, longer minutes: the clips' own lengths count, not --clip-seconds.
    Stimulus.objects.filter(study=study).update(duration=12.0)
    call_command("plan", study="timed", effect=1.5, clip_sd=0.0, participants="10",
                 clips="2", studies=2, bootstrap=20, trials=8)
    printed = capsys.readouterr().out
    fixed, trials = duration.session_seconds(study)
    rescaled = (fixed + 8 * sum(s for _, s in trials) / len(trials)) / 60
    assert "rescaled from its 4 to 8 main trials" in printed
    assert f"Minutes per participant: {rescaled:.1f}," in printed


@pytest.mark.django_db
def test_plan_for_a_study_without_trials_says_its_minutes_are_assumed(capsys):
    from studyapp.survey.models import Study

    kind = Study._meta.get_field("study_type").default
    Study.objects.create_study(kind, "empty", "Movement study", clips_per_trial=3)
    call_command("plan", study="empty", effect=1.5, clip_sd=0.0, participants="10", clips="2",
                 studies=2, bootstrap=20, clip_seconds=4.0)
    printed = capsys.readouterr().out
    assert "Minutes per participant:" in printed
    assert "assumed: 10 trials of 4 s clips" in printed and "plans no main trial yet" in printed
    with pytest.raises(CommandError, match="Unknown study 'nope'"):
        call_command("plan", study="nope")


def test_plan_without_a_study_says_its_minutes_are_assumed(capsys):
    call_command("plan", study_type="pairwise", effect=1.5, clip_sd=0.0, trials=6,
                 participants="10", clips="2", studies=2, bootstrap=20, clip_seconds=3.0)
    assert "Minutes per participant: 4.1, assumed: 6 trials of 3 s clips" in capsys.readouterr().out
