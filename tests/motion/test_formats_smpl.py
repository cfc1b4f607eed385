"""SMPL-based imports: AMASS, MotionCritic, ACTOR and MDM meshes, through smplx.

The body models are small synthetic files in the real layout (see body_model_files);
the licensed ones are never needed.
"""

import numpy as np
import pytest

from motion.body_models import BodyModelError, find_body_model, rotation_6d_to_matrix
from motion.formats import FormatError, load_motions
from motion.ops import axis_rotation
from tests.motion.body_model_files import rest_joints, write_smpl, write_smplh


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    root = tmp_path_factory.mktemp("body_models")
    write_smpl(root)
    write_smplh(root, "male")
    return root


def turn_z(angle):
    cos, sin = np.cos(angle), np.sin(angle)
    return np.array([[cos, -sin, 0], [sin, cos, 0], [0, 0, 1.0]])


def test_missing_body_model_names_the_file_where_to_get_it_and_where_to_put_it(tmp_path,
                                                                                 monkeypatch):
    monkeypatch.delenv("STUDY_BODY_MODELS", raising=False)
    with pytest.raises(BodyModelError) as error:
        find_body_model("smpl", "neutral")
    message = str(error.value)
    assert "SMPL_NEUTRAL.pkl" in message and "https://smpl.is.tue.mpg.de" in message
    assert "--body-models DIR" in message and "STUDY_BODY_MODELS" in message
    with pytest.raises(BodyModelError, match=r"smplh/SMPLH_FEMALE.npz is missing.*mano"):
        find_body_model("smplh", "female", tmp_path)
    monkeypatch.setenv("STUDY_BODY_MODELS", str(tmp_path))
    write_smpl(tmp_path)
    assert find_body_model("smpl").name == "SMPL_NEUTRAL.pkl"


def test_amass_smplh_poses_give_smpl22_joints_y_up_with_the_body(tmp_path, models):
    frames = 5
    poses = np.zeros((frames, 156))
    poses[:, 2] = np.linspace(0, np.pi / 2, frames)  # the root turns about AMASS's z (up)
    trans = np.zeros((frames, 3))
    trans[:, 0] = np.linspace(0, 1, frames)
    np.savez(tmp_path / "walk_poses.npz", poses=poses, trans=trans, betas=np.zeros(16),
             gender=np.array("male"), mocap_framerate=np.array(120.0))
    [motion] = load_motions(tmp_path / "walk_poses.npz", "amass", body_models=models)
    assert (motion.skeleton, motion.fps, motion.frames) == ("smpl22", 120.0, frames)
    assert motion.has_body and motion.vertices.shape == (frames, 6890, 3)
    rest = rest_joints(52)[:22]  # the synthetic model's joints, in AMASS's (z-up) frame
    last = (rest - rest[0]) @ turn_z(np.pi / 2).T + rest[0] + trans[-1]
    np.testing.assert_allclose(motion.joints[-1], last @ axis_rotation("z", "y").T, atol=1e-5)
    [no_body] = load_motions(tmp_path / "walk_poses.npz", "amass", body_models=models,
                             vertices=False, fps=30)
    assert not no_body.has_body and no_body.fps == 30


def test_amass_smpl_files_and_bad_files_in_a_folder(tmp_path, models):
    np.savez(tmp_path / "a.npz", poses=np.zeros((4, 72)), trans=np.zeros((4, 3)),
             betas=np.zeros(10), gender="neutral", mocap_framerate=60.0)
    np.savez(tmp_path / "shape.npz", betas=np.zeros(16), gender="male")
    np.savez(tmp_path / "c.npz", poses=np.zeros((4, 99)), trans=np.zeros((4, 3)),
             mocap_framerate=60.0)
    np.savez(tmp_path / "d.npz", poses=np.zeros((4, 156)), trans=np.zeros((4, 3)),
             gender="female", mocap_framerate=60.0)
    motions = load_motions(tmp_path, "amass", body_models=models)
    assert [m.skeleton for m in motions] == ["smpl24"]
    problems = "\n".join(motions.problems)
    assert "shape.npz: no key 'poses', 'trans'" in problems
    assert "c.npz: poses has shape (4, 99)" in problems
    assert "d.npz" in problems and "SMPLH_FEMALE.npz is missing" in problems


def rot6d_motion(frames=6, turn=0.0):
    """Return a MotionCritic/MDM motion (25, 6, T): identity rotations, the root turned."""
    matrices = np.tile(np.eye(3), (frames, 24, 1, 1))
    cos, sin = np.cos(turn), np.sin(turn)
    matrices[:, 0] = [[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]]  # about y
    six = matrices[..., :2, :].reshape(frames, 24, 6)
    motion = np.zeros((25, 6, frames))
    motion[:24] = six.transpose(1, 2, 0)
    motion[24, 2] = np.linspace(0.3, 1.3, frames)  # moves along z
    return motion


def test_rotation_6d_keeps_the_first_two_rows():
    rotation = turn_z(0.7) @ axis_rotation("y", "z")
    np.testing.assert_allclose(rotation_6d_to_matrix(rotation[:2].reshape(6)), rotation,
                               atol=1e-12)


def test_motioncritic_files_give_four_prompted_smpl24_motions(tmp_path, models):
    prompts = ["Warm up", "Jump", "Run", "Throw"]
    np.savez(tmp_path / "pair.npz", {"prompt": prompts,
                                     "motion": [rot6d_motion()[None] for _ in prompts]})
    motions = load_motions(tmp_path / "pair.npz", "motioncritic", body_models=models)
    assert [m.text for m in motions] == prompts and [m.action for m in motions] == prompts
    assert [m.meta["choice"] for m in motions] == list("ABCD")
    first = motions[0]
    assert first.skeleton == "smpl24" and first.has_body and first.frames == 6
    # Translated by translation - translation[0], like MDM's rotation2xyz.
    np.testing.assert_allclose(first.joints[-1] - first.joints[0], np.tile([0, 0, 1.0], (24, 1)),
                               atol=1e-5)
    np.savez(tmp_path / "pair.npz", {"prompt": prompts, "motion": [np.zeros((1, 24, 6, 60))] * 4})
    with pytest.raises(FormatError, match=r"motion\[0\] has shape \(24, 6, 60\); expected"):
        load_motions(tmp_path / "pair.npz", "motioncritic", body_models=models)
    np.savez(tmp_path / "pair.npz", {"text": prompts})
    with pytest.raises(FormatError, match="no key 'prompt', 'motion'"):
        load_motions(tmp_path / "pair.npz", "motioncritic", body_models=models)


def test_actor_vertices_become_smpl24_motions_upright_with_faces(tmp_path, models):
    from motion.body_models import load_body_model

    model = load_body_model("smpl", "neutral", models)
    _, surface = model.forward(np.zeros((4, 3)), np.zeros((4, 69)))
    down = surface * [1, -1, -1]  # ACTOR's bodies are y down
    generation = np.stack([np.stack([down, down + 0.1])] * 2).transpose(0, 1, 3, 4, 2)
    np.save(tmp_path / "generation.npy", generation)  # (samples 2, actions 2, 6890, 3, T 4)
    motions = load_motions(tmp_path, "actor", body_models=models, action_names=["run", "jump"])
    assert [m.action for m in motions] == ["run", "jump"] * 2
    assert all(m.skeleton == "smpl24" and m.has_body for m in motions)
    assert (motions[0].joints[:, 15, 1] > motions[0].joints[:, 7, 1]).all()
    np.testing.assert_array_equal(motions[0].faces, model.faces)
    with pytest.raises(FormatError, match="2 action classes but 3 action names"):
        load_motions(tmp_path, "actor", body_models=models, action_names=["a", "b", "c"])
    with pytest.raises(FormatError, match="no faces or joints.*SMPL_NEUTRAL.pkl"):
        load_motions(tmp_path, "actor", body_models=tmp_path)


def test_mdm_mesh_without_results_regresses_joints_from_the_smpl_model(tmp_path, models):
    from motion.body_models import load_body_model

    model = load_body_model("smpl", "neutral", models)
    _, surface = model.forward(np.zeros((3, 3)), np.zeros((3, 69)))
    np.save(tmp_path / "sample00_rep00_smpl_params.npy", {
        "motion": np.zeros((25, 6, 3)), "vertices": surface.transpose(1, 2, 0),
        "faces": model.faces, "text": "a person stands", "length": 3})
    [motion] = load_motions(tmp_path / "sample00_rep00_smpl_params.npy", "mdm",
                            body_models=models)
    np.testing.assert_allclose(motion.joints[0], rest_joints(24)[:22], atol=1e-5)
    assert motion.text == "a person stands" and motion.has_body
