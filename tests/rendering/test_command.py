"""The render command turns interchange files into videos, posters and a record."""

import json

import pytest
from django.core.management import CommandError, call_command

from motion.formats import npz
from tests.rendering.conftest import make_figure


def test_render_command_writes_videos_posters_and_record(tmp_path, capsys):
    real = [make_figure(frames=6), make_figure(frames=6, phase=2.0)]
    real = npz.save(tmp_path / "real.npz", real)
    fake = npz.save(tmp_path / "fake.npz", [make_figure(frames=6, speed=1.0, source="gen")])
    out = tmp_path / "out"
    call_command("render", str(real), str(fake), "--out", str(out), "--size", "96", verbosity=0)
    assert len(list(out.glob("*.mp4"))) == 3 and len(list(out.glob("*.png"))) == 3
    record = json.loads((out / "renders.json").read_text())
    assert [c["source"] for c in record["clips"]] == ["real", "real", "gen"]
    assert "rendered 3 of 3 clips" in capsys.readouterr().out


def test_render_command_refuses_user_mistakes(tmp_path):
    with pytest.raises(CommandError, match="does not exist"):
        call_command("render", str(tmp_path / "missing.npz"), "--out", str(tmp_path))
    motions = npz.save(tmp_path / "m.npz", [make_figure(frames=2)])
    with pytest.raises(CommandError, match="even"):
        call_command("render", str(motions), "--out", str(tmp_path), "--size", "95")
