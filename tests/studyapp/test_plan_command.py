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
