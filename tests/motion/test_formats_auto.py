"""auto on folders: per-file detection, a table of what was found, every group read,
skipped files named with the reason; mixed skeletons get the fix; prompts from names."""

import io
import re
import pickle

import numpy as np
import pytest
from django.core.management import CommandError, call_command

from motion.formats import load_motions, npz
from motion.formats.auto import detect
from motion.formats.base import prompt_from_name
from tests.motion.bvh_layouts import write as write_bvh
from tests.motion.test_formats_text_to_motion import walking


def run(*args):
    output, errors = io.StringIO(), io.StringIO()
    call_command("import_motions", *map(str, args), stdout=output, stderr=errors)
    return output.getvalue(), errors.getvalue()


def mixed_folder(tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    np.save(folder / "a_person_is_boxing.npy", walking(8))
    np.save(folder / "sample0_repeat0_len8.npy", walking(8, seed=1))
    write_bvh(folder / "dance.bvh", "lafan1")
    np.save(folder / "broken.npy", np.zeros((8, 22, 2)))
    with open(folder / "tracks.pkl", "wb") as handle:
        pickle.dump({"something": [1, 2, 3]}, handle)
    (folder / "notes.txt").write_text("not a motion file")
    return folder


def test_a_mixed_folder_reads_every_group_and_names_what_it_skipped(tmp_path):
    motions = load_motions(mixed_folder(tmp_path), "auto")
    by_skeleton = {}
    for motion in motions:
        by_skeleton.setdefault(motion.skeleton, []).append(motion)
    assert len(by_skeleton["smpl22"]) == 2 and len(motions) == 3
    assert sorted(str(m.text) for m in by_skeleton["smpl22"]) == ["None", "a person is boxing"]
    table = motions.notes[-1]
    assert "format" in table and "skeleton" in table and "fps" in table
    assert re.search(r"joints +smpl22 +20 +2", table) and re.search(r"bvh +bvh_\w+ +30 +1", table)
    skipped = "\n".join(motions.problems)
    assert "broken.npy: an array of shape (8, 22, 2), which no format has" in skipped
    assert "tracks.pkl: a .pkl file with keys something, which no format has" in skipped
    assert "notes.txt" not in skipped


def test_import_motions_refuses_mixed_skeletons_with_the_fix_or_splits_them(tmp_path):
    folder = mixed_folder(tmp_path)
    with pytest.raises(CommandError, match=r"2 skeletons .*--skeleton smpl22.*--per-skeleton"):
        run(folder, "--format", "auto", "--out", tmp_path / "out.npz")
    with pytest.raises(CommandError, match=r"sources imported, real.*--source NAME"):
        run(folder, "--format", "auto", "--skeleton", "smpl22", "--fps", "20", "--out",
            tmp_path / "one.npz")
    output, errors = run(folder, "--format", "auto", "--skeleton", "smpl22", "--fps", "20",
                         "--source", "real",
                         "--out", tmp_path / "one.npz")
    assert "wrote 3 smpl22 motions" in output and "skipped: " in errors
    output, _ = run(folder, "--format", "auto", "--per-skeleton", "--out", tmp_path / "out.npz")
    written = sorted(p.name for p in tmp_path.glob("out_*.npz"))
    assert len(written) == 2 and "out_smpl22.npz" in written
    assert [m.text for m in npz.load(tmp_path / "out_smpl22.npz")][0] == "a person is boxing"


def test_prompts_from_file_names_unless_a_prompt_file_says_otherwise(tmp_path):
    assert prompt_from_name("a_person_is_boxing") == "a person is boxing"
    assert prompt_from_name("sample0_repeat1_len60") is None
    assert prompt_from_name("walk") is None
    folder = tmp_path / "t2m"
    folder.mkdir()
    np.save(folder / "a_person_is_boxing.npy", walking(6))
    np.save(folder / "a_person_jumps_twice.npy", walking(6, seed=2))
    assert [m.text for m in load_motions(folder, "joints")] == [
        "a person is boxing", "a person jumps twice"]
    prompts = tmp_path / "prompts.txt"
    prompts.write_text("one\ntwo\n")
    assert [m.text for m in load_motions(folder, "joints", texts=prompts)] == ["one", "two"]


def test_a_file_of_no_known_kind_says_what_it_holds(tmp_path):
    from motion.formats import FormatError

    path = tmp_path / "x.joblib"
    with open(path, "wb") as handle:
        pickle.dump([{"a": 1}], handle)
    with pytest.raises(FormatError, match="holding list of 1 dict, which no format has"):
        detect(path)
    (tmp_path / "x.fbx").write_bytes(b"Kaydara")
    with pytest.raises(FormatError, match="cannot tell the format of a .fbx file"):
        detect(tmp_path / "x.fbx")


def test_a_format_module_brings_its_own_file_endings(tmp_path):
    """A format that reads another kind of file declares its endings (``SUFFIXES``): auto
    then surveys such files in a folder, and no shared list names them."""
    import types

    from motion.formats import base
    from motion.formats.auto import survey
    from motion.motion import Motion

    def load(path, **options):
        joints = np.loadtxt(path, delimiter=",").reshape(-1, 22, 3)
        return [Motion(joints=joints, skeleton="smpl22", fps=20.0, source="real",
                       action="walk")]

    def detect(probe):
        return "a toy CSV" if probe.suffix == ".toycsv" else None

    toy = types.SimpleNamespace(load=load, detect=detect, SUFFIXES=(".toycsv",))
    np.savetxt(tmp_path / "walk.toycsv", walking(4, 22).reshape(4, -1), delimiter=",")
    base._FORMATS.add("toy_endings", toy)
    try:
        groups, skipped = survey(tmp_path)
        assert list(groups) == ["toy_endings"] and not skipped
    finally:
        base._FORMATS.pop("toy_endings")
