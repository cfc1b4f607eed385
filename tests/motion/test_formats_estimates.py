"""Pose estimators and simulators: WHAM, 4D-Humans/PHALP, VIBE, TRAM, AIST++, PHC and AMP
poselib files, written in their layouts, read upright, on the floor, of plausible height,
with tracks chosen by --person and the frame stated."""

import io

import numpy as np
import pytest
from django.core.management import CommandError, call_command

from motion.formats import FormatError, load_motions, npz
from motion.skeletons import get_skeleton
from tests.motion.body_model_files import write_smpl
from tests.motion.format_examples import EXAMPLES, FRAMES

HEAD, PELVIS, ANKLES = 15, 0, [7, 8]


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    root = tmp_path_factory.mktemp("body_models")
    write_smpl(root)
    return root


def upright_on_the_floor(motion, floor=True):
    joints = motion.joints
    up = get_skeleton(motion.skeleton).up_index
    assert (joints[:, HEAD, up] > joints[:, PELVIS, up]).all()
    assert (joints[:, PELVIS, up] > joints[:, ANKLES, up].max(axis=1)).all()
    height = joints[:, :, up].max(axis=1) - joints[:, :, up].min(axis=1)
    assert (1.0 < height).all() and (height < 2.3).all()
    if floor:
        assert abs(np.median(joints[:, :, up].min(axis=1))) < 0.03


@pytest.mark.parametrize("name", ["wham", "vibe", "phalp", "tram", "aistpp", "phc"])
def test_smpl_outputs_stand_upright_on_the_floor(tmp_path, models, name):
    path, _ = EXAMPLES[name](tmp_path)
    motions = load_motions(path, name, body_models=models)
    for motion in motions:
        assert motion.skeleton == "smpl24" and motion.frames >= 4 and motion.has_body
        upright_on_the_floor(motion)
    frame = motions[0].meta["frame"]
    assert frame == {"vibe": "camera", "phalp": "camera"}.get(name, "world")


def test_wham_tracks_by_person_and_frame(tmp_path, models):
    path, _ = EXAMPLES["wham"](tmp_path)
    both = load_motions(path, "wham", body_models=models)
    assert [m.meta["person"] for m in both] == ["0", "3"]
    assert "2 tracked people (0, 3)" in both.notes[0] and "--person ID" in both.notes[0]
    [one] = load_motions(path, "wham", body_models=models, person="3", frame="camera")
    assert one.meta["person"] == "3" and one.meta["frame"] == "camera"
    assert "turned upright" in one.meta["placed"]
    upright_on_the_floor(one)
    with pytest.raises(FormatError, match=r"no person '7'; the file's tracks are 0, 3 "
                                          r"\(pass --person ID\)"):
        load_motions(path, "wham", body_models=models, person="7")
    with pytest.raises(FormatError, match="frame 'image'"):
        load_motions(path, "wham", body_models=models, frame="image")


def test_phalp_makes_one_motion_per_track_of_the_frames_it_was_seen_in(tmp_path, models):
    path, _ = EXAMPLES["phalp"](tmp_path)
    motions = load_motions(path, "phalp", body_models=models)
    assert [(m.meta["person"], m.frames) for m in motions] == [("1", FRAMES), ("2", 4)]
    assert "2 tracks over 6 frames (1: 6, 2: 4 frames)" in motions.notes[0]


def test_aistpp_is_in_metres_with_its_genre_and_60_fps(tmp_path, models):
    path, _ = EXAMPLES["aistpp"](tmp_path)
    [motion] = load_motions(path, "aistpp", body_models=models)
    assert motion.fps == 60.0 and motion.action == "break"
    np.testing.assert_allclose(motion.joints[0, PELVIS, [0, 2]], [0.1, 0.2], atol=1e-4)


def test_phc_torch_tensors_and_z_up_are_read(tmp_path, models):
    path, _ = EXAMPLES["phc"](tmp_path)
    motions = load_motions(path, "auto", body_models=models)
    assert [m.meta["clip"] for m in motions] == ["0-ACCAD_walk0_poses", "0-ACCAD_walk1_poses"]
    assert motions[0].fps == 30.0
    np.testing.assert_allclose(motions[0].joints[0, PELVIS], [0, 0.95, 0], atol=1e-4)


def test_amp_poselib_is_its_own_z_up_skeleton_with_sides(tmp_path):
    path, _ = EXAMPLES["amp_poselib"](tmp_path)
    [motion] = load_motions(path, "auto")
    skeleton = get_skeleton(motion.skeleton)
    assert skeleton.up == "z" and skeleton.n_joints == 15 and motion.fps == 60.0
    assert {skeleton.joint_names[j] for j in skeleton.left} >= {"left_thigh", "left_hand"}
    feet = [skeleton.joint_names.index(n) for n in ("left_foot", "right_foot")]
    np.testing.assert_allclose(motion.joints[:, feet, 2], 0.06, atol=1e-5)
    np.testing.assert_allclose(motion.joints[-1, 0], [0.5, 0, 0.89], atol=1e-6)


def test_import_motions_person_and_the_missing_model(tmp_path, models, monkeypatch):
    path, _ = EXAMPLES["wham"](tmp_path)
    output = io.StringIO()
    call_command("import_motions", str(path), "--format", "auto", "--person", "0",
                 "--body-models", str(models), "--out", str(tmp_path / "out.npz"),
                 stdout=output, stderr=io.StringIO())
    assert "detected format 'wham'" in output.getvalue()
    assert len(npz.load(tmp_path / "out.npz")) == 1
    monkeypatch.delenv("STUDY_BODY_MODELS", raising=False)
    with pytest.raises(CommandError, match=r"SMPL_NEUTRAL.pkl.*smpl.is.tue.mpg.de.*--body-models"):
        call_command("import_motions", str(path), "--format", "wham", "--out",
                     str(tmp_path / "x.npz"), stdout=io.StringIO(), stderr=io.StringIO())


@pytest.mark.parametrize("fmt", ["wham", "phc", "auto"])
def test_a_tampered_joblib_file_is_refused_and_nothing_runs(tmp_path, models, fmt):
    import joblib

    from tests.motion.untrusted_files import SYSTEM, RunsCommand

    marker = tmp_path / "ran"
    tracks = {0: {"pose": np.zeros((4, 72)), "trans": np.zeros((4, 3)), "pose_aa": np.zeros((4, 72)),
                  "hook": RunsCommand(marker)}}
    joblib.dump(tracks, tmp_path / "output.pkl")
    with pytest.raises(FormatError, match=f"output.pkl.*refused.*{SYSTEM}"):
        load_motions(tmp_path / "output.pkl", fmt, body_models=models)
    assert not marker.exists()


def test_a_tampered_smplx_model_is_refused(tmp_path):
    from tests.motion.body_model_files import write_smplx
    from tests.motion.format_examples import smplx as beat2
    from tests.motion.untrusted_files import SYSTEM, RunsCommand

    marker = tmp_path / "ran"
    path = write_smplx(tmp_path / "models")
    with np.load(path, allow_pickle=True) as data:  # the test's own file, to tamper with
        arrays = {key: data[key] for key in data.files}
    arrays["joint2num"] = np.array([RunsCommand(marker)], dtype=object)
    np.savez(path, **arrays)
    beat, _ = beat2(tmp_path)
    with pytest.raises(FormatError, match=f"SMPLX_NEUTRAL.npz.*refused.*{SYSTEM}"):
        load_motions(beat, "smplx", body_models=tmp_path / "models")
    assert not marker.exists()
