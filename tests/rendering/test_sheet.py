"""Contact sheets of a folder of rendered clips, labelled from the render records."""

import pytest
from PIL import Image

from rendering import render_set
from rendering.sheet import find_clips, write_sheet
from tests.rendering.conftest import make_figure


def test_a_sheet_shows_every_clip_of_a_folder_with_its_label(tmp_path):
    render_set([make_figure(frames=6, speed=1.0), make_figure(frames=6, source="a2m")],
               tmp_path / "renders", size=64, progress=False)
    render_set([make_figure(frames=6, phase=2.0, source="broken")], tmp_path / "renders" / "extras",
               size=64, progress=False)
    clips = find_clips(tmp_path)
    assert [c.label for c in clips] == ["real · walk", "a2m · walk", "broken · walk"]
    assert [c.group for c in clips] == ["renders", "renders", "renders/extras"]
    sheet = Image.open(write_sheet(tmp_path, tmp_path / "sheet.png", moments=3, size=48,
                                   columns=2))
    assert sheet.width > 2 * 3 * 48 and sheet.height > 2 * 48


def test_an_empty_folder_is_refused(tmp_path):
    with pytest.raises(ValueError, match="no mp4 clips"):
        write_sheet(tmp_path, tmp_path / "sheet.png")
