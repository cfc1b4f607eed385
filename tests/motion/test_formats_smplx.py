"""SMPL-X motions in BEAT2/EMAGE's, AMASS's SMPL-X and Motion-X's layouts, posed with a
synthetic SMPL-X model through smplx: smpl22 or with fingers, upright, on the floor."""

import io

import numpy as np
import pytest
from django.core.management import CommandError, call_command

from motion.formats import FormatError, load_motions
from motion.formats.auto import detect
from motion.skeletons import get_skeleton
from tests.motion.body_model_files import smplx_rest_joints, write_smplx
from tests.motion.format_examples import FRAMES, Z_UP, smplx_poses

BODY = list(range(22))


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    root = tmp_path_factory.mktemp("body_models")
    write_smplx(root)
    return root


def write_layouts(folder):
    beat = folder / "2_scott_0_1_1.npz"
    np.savez(beat, poses=smplx_poses(), trans=np.zeros((FRAMES, 3)), betas=np.zeros(300),
             expressions=np.zeros((FRAMES, 100)), mocap_frame_rate=30)
    amass = folder / "stageii.npz"
    trans = np.tile([0.0, 0.95, 0.0], (FRAMES, 1)) @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.]]).T
    np.savez(amass, surface_model_type="smplx", gender="neutral", poses=smplx_poses(root=Z_UP),
             trans=trans - [0, 0, 0.95], betas=np.zeros(16), mocap_frame_rate=120.0)
    poses = smplx_poses()
    motion_x = np.zeros((FRAMES, 322))
    motion_x[:, :66] = poses[:, :66]
    motion_x[:, 66:156] = poses[:, 75:165]
    motion_x[:, 309:312] = [0.2, 0.0, 0.0]
    np.save(folder / "idea400_walk.npy", motion_x)
    return beat, amass, folder / "idea400_walk.npy"


def test_three_layouts_are_detected_and_stand_upright_on_the_floor(tmp_path, models):
    beat, amass, motion_x = write_layouts(tmp_path)
    assert "BEAT2/EMAGE" in detect(beat)[1] and "AMASS SMPL-X" in detect(amass)[1]
    assert "Motion-X" in detect(motion_x)[1]
    rest = smplx_rest_joints()[BODY]
    for path, fps in ((beat, 30.0), (amass, 120.0), (motion_x, 30.0)):
        [motion] = load_motions(path, "auto", body_models=models)
        assert (motion.skeleton, motion.fps, motion.frames) == ("smpl22", fps, FRAMES), path
        assert motion.has_body and motion.vertices.shape[1] == 10475
        # The first frame: the rest pose with the knee straight, on the floor, y up.
        np.testing.assert_allclose(motion.joints[0] - motion.joints[0, :1],
                                   rest - rest[:1], atol=1e-4)
        assert abs(motion.joints[:, :, 1].min(axis=1).mean() - rest[:, 1].min()) < 0.05
    [amass_motion] = load_motions(amass, "smplx", body_models=models)
    assert amass_motion.meta["up"] == "z" and amass_motion.meta["layout"] == "AMASS SMPL-X"


def test_hands_are_kept_or_dropped(tmp_path, models):
    beat, _, _ = write_layouts(tmp_path)
    [body] = load_motions(beat, "smplx", body_models=models)
    [hands] = load_motions(beat, "smplx", body_models=models, hands=True, vertices=False)
    skeleton = get_skeleton(hands.skeleton)
    assert skeleton.n_joints == 52 and "left_index1" in skeleton.joint_names
    assert {skeleton.joint_names[j] for j in skeleton.left} >= {"left_thumb3", "left_wrist"}
    np.testing.assert_allclose(hands.joints[:, :22], body.joints, atol=1e-5)
    tip = skeleton.joint_names.index("left_index3")
    assert not np.allclose(hands.joints[0, tip], hands.joints[-1, tip], atol=1e-3), "fingers curl"


def test_the_missing_model_names_the_file_where_to_get_it_and_where_to_put_it(tmp_path,
                                                                              monkeypatch):
    beat, _, _ = write_layouts(tmp_path)
    monkeypatch.delenv("STUDY_BODY_MODELS", raising=False)
    with pytest.raises(FormatError) as error:
        load_motions(beat, "smplx")
    message = str(error.value)
    assert "SMPLX_NEUTRAL.npz" in message and "https://smpl-x.is.tue.mpg.de" in message
    assert "DIR/smplx/SMPLX_NEUTRAL.npz" in message and "--body-models DIR" in message
    with pytest.raises(CommandError, match=r"smplx/SMPLX_NEUTRAL.npz is missing"):
        call_command("import_motions", str(beat), "--format", "auto", "--body-models",
                     str(tmp_path), "--out", str(tmp_path / "o.npz"), stdout=io.StringIO(),
                     stderr=io.StringIO())


def test_import_motions_smplx_with_hands(tmp_path, models):
    beat, _, _ = write_layouts(tmp_path)
    output = io.StringIO()
    call_command("import_motions", str(beat), "--format", "smplx", "--hands", "--joints-only",
                 "--body-models", str(models), "--out", str(tmp_path / "o.npz"), stdout=output,
                 stderr=io.StringIO())
    assert "wrote 1 smplx_" in output.getvalue()
