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


def test_a_stimulus_build_folder_takes_its_clips_from_the_cache_beside_it(tmp_path):
    """build_stimuli writes manifest.json to <var>/stimuli/<slug> and the clips to
    <var>/stimuli/cache/renders: the sheet of the study's folder shows them, labelled from
    the manifest."""
    import json

    motions = [make_figure(frames=6), make_figure(frames=6, phase=2.0, source="a2m")]
    report = render_set(motions,
                        tmp_path / "stimuli" / "cache" / "renders", size=64, progress=False)
    (tmp_path / "stimuli" / "cache" / "renders" / "renders.json").unlink()
    study = tmp_path / "stimuli" / "my-study"
    study.mkdir()
    (study / "manifest.json").write_text(json.dumps({"clips": [
        {"source": motion.source, "action": "walk", "role": "judged", "motion_hash": "m",
         "video_hash": clip.video.stem} for motion, clip in zip(motions, report.clips)]}))
    clips = find_clips(study)
    assert sorted(c.label for c in clips) == ["a2m · walk · judged", "real · walk · judged"]
    assert Image.open(write_sheet(study, tmp_path / "sheet.png", moments=2, size=32)).width
    elsewhere = tmp_path / "other"
    with pytest.raises(FileNotFoundError, match="pass the build's cache folder"):
        find_clips(study, cache=elsewhere)
