"""BVH files as their own skeleton or mapped onto smpl22/smpl24; the interchange file's
texts, bodies and hierarchies; import_motions on the new formats."""

import io
import pickle

import numpy as np
import pytest
from django.core.management import CommandError, call_command

from motion.formats import FormatError, bvh, load_motions, npz
from motion.motion import Motion
from motion.skeletons import get_skeleton, is_custom
from tests.motion.test_formats import FIXTURE, write_bvh
from tests.motion.test_formats_text_to_motion import PROMPTS, walking, write_results

# MoMask's joints2bvh hierarchy (HumanML3D's 22 joints), offsets in metres.
MOMASK = [("Hips", -1, (0, 0, 0)),
          ("LeftUpLeg", 0, (0.1, -0.05, 0)), ("LeftLeg", 1, (0, -0.4, 0)),
          ("LeftFoot", 2, (0, -0.4, 0)), ("LeftToe", 3, (0, -0.05, 0.12)),
          ("RightUpLeg", 0, (-0.1, -0.05, 0)), ("RightLeg", 5, (0, -0.4, 0)),
          ("RightFoot", 6, (0, -0.4, 0)), ("RightToe", 7, (0, -0.05, 0.12)),
          ("Spine", 0, (0, 0.1, 0)), ("Spine1", 9, (0, 0.13, 0)), ("Spine2", 10, (0, 0.1, 0)),
          ("Neck", 11, (0, 0.15, 0)), ("Head", 12, (0, 0.1, 0)),
          ("LeftShoulder", 11, (0.07, 0.1, 0)), ("LeftArm", 14, (0.1, 0, 0)),
          ("LeftForeArm", 15, (0.26, 0, 0)), ("LeftHand", 16, (0.25, 0, 0)),
          ("RightShoulder", 11, (-0.07, 0.1, 0)), ("RightArm", 18, (-0.1, 0, 0)),
          ("RightForeArm", 19, (-0.26, 0, 0)), ("RightHand", 20, (-0.25, 0, 0))]


def momask_bvh(path, frames=3, names=None):
    joints = [(names[i] if names else name, parent, offset)
              for i, (name, parent, offset) in enumerate(MOMASK)]
    rows = [[0.0, 0.95, 0.1 * t] + [0.0, 0.0, 10.0 * t] + [0.0] * 3 * 21 for t in range(frames)]
    return write_bvh(path, joints, rows)


def test_bvh_is_its_own_skeleton_with_sides_and_comments_tolerated(tmp_path):
    path = momask_bvh(tmp_path / "walk.bvh")
    text = path.read_text().replace("HIERARCHY", "#name: walk\n# converted\nHIERARCHY", 1)
    path.write_text(text)
    [motion] = load_motions(path, "bvh")
    skeleton = get_skeleton(motion.skeleton)
    assert is_custom(skeleton.name) and skeleton.name.startswith("bvh_")
    assert skeleton.joint_names[:3] == ("Hips", "LeftUpLeg", "LeftLeg")
    assert "LeftUpLeg" in [skeleton.joint_names[j] for j in skeleton.left]
    assert "RightArm" in [skeleton.joint_names[j] for j in skeleton.right]
    assert skeleton.n_joints == 22 + 5, "End Sites with length (the write_bvh fixture's) are kept"
    assert motion.action == "walk" and motion.text is None, "the action is the file's name"
    # The same hierarchy is the same skeleton; it travels in the interchange file.
    npz.save(tmp_path / "out.npz", [motion])
    [back] = npz.load(tmp_path / "out.npz")
    assert back.skeleton == motion.skeleton
    np.testing.assert_allclose(back.joints, motion.joints)


def test_bvh_maps_momask_and_smpl2bvh_names_onto_smpl22_and_smpl24(tmp_path):
    [momask] = load_motions(momask_bvh(tmp_path / "a.bvh"), "bvh", skeleton="smpl22")
    assert momask.skeleton == "smpl22" and momask.meta["bvh_joints"]["left_foot"] == "LeftToe"
    np.testing.assert_allclose(momask.joints[0, 0], [0, 0.95, 0], atol=1e-6)
    smpl_names = ["Pelvis", "Left_hip", "Left_knee", "Left_ankle", "Left_foot", "Right_hip",
                  "Right_knee", "Right_ankle", "Right_foot", "Spine1", "Spine2", "Spine3",
                  "Neck", "Head", "Left_collar", "Left_shoulder", "Left_elbow", "Left_wrist",
                  "Right_collar", "Right_shoulder", "Right_elbow", "Right_wrist"]
    [smpl] = load_motions(momask_bvh(tmp_path / "b.bvh", names=smpl_names), "bvh",
                          skeleton="smpl22", action="walk")
    assert smpl.meta["bvh_joints"]["left_hip"] == "Left_hip" and smpl.action == "walk"
    np.testing.assert_allclose(smpl.joints, momask.joints, atol=1e-6)
    [cmu] = load_motions(FIXTURE, "bvh", skeleton="smpl24")
    assert cmu.skeleton == "smpl24" and cmu.meta["bvh_joints"]["spine3"] == "Neck1"


def test_bvh_folder_with_prompts_and_a_bad_file(tmp_path):
    momask_bvh(tmp_path / "sample0.bvh")
    momask_bvh(tmp_path / "sample1.bvh")
    (tmp_path / "sample2.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    (tmp_path / "prompts.txt").write_text("\n".join(PROMPTS[:3]))
    motions = load_motions(tmp_path, "bvh", skeleton="smpl22")
    assert [m.text for m in motions] == PROMPTS[:2] and motions[0].action == PROMPTS[0]
    assert len(motions.problems) == 1 and "sample2.bvh" in motions.problems[0]


def test_npz_round_trips_texts_and_bodies():
    vertices = np.random.default_rng(0).normal(size=(6, 8, 3)).astype(np.float32)
    faces = np.array([[0, 1, 2], [3, 4, 7]])
    motions = [Motion(walking(6, seed=i), "smpl22", 20.0, "unknown", "mdm", text=PROMPTS[i],
                      vertices=vertices + i, faces=faces) for i in range(2)]
    path = npz.save("/tmp/interchange-test.npz", motions)
    loaded = npz.load(path)
    assert [m.text for m in loaded] == PROMPTS[:2]
    np.testing.assert_allclose(loaded[1].vertices, vertices + 1)
    np.testing.assert_array_equal(loaded[0].faces, faces)
    with np.load(path) as data:
        assert data["texts"].dtype.kind == "U" and data["vertices"].shape == (2, 6, 8, 3)
    plain = [Motion(walking(6), "smpl22", 20.0, "walk", "mdm")]
    with np.load(npz.save("/tmp/interchange-test.npz", plain)) as data:
        assert "texts" not in data and "vertices" not in data
    with pytest.raises(FormatError, match="1 of 2 motions carry a body surface"):
        npz.save("/tmp/interchange-test.npz", plain + motions[:1])


def test_motions_with_a_custom_skeleton_survive_a_spawned_process():
    momask = bvh.BvhMotion(("Root", "Left", "Right"), (-1, 0, 0),
                           np.zeros((3, 3), np.float32), np.ones((2, 3, 3), np.float32), 20.0,
                           1.0, path="x.bvh")
    motion = bvh.own_skeleton(momask)
    state = pickle.dumps(motion)
    from motion import skeletons

    definition = skeletons._REGISTRY.pop(motion.skeleton)  # as in a fresh process
    skeletons._CUSTOM.discard(motion.skeleton)
    back = pickle.loads(state)
    assert get_skeleton(back.skeleton) == definition


def run(*args):
    output, errors = io.StringIO(), io.StringIO()
    call_command("import_motions", *map(str, args), stdout=output, stderr=errors)
    return output.getvalue(), errors.getvalue()


def test_import_motions_mdm_results_with_prompts(tmp_path):
    write_results(tmp_path / "results.npy", count=4)
    output, _ = run(tmp_path / "results.npy", "--format", "mdm", "--out", tmp_path / "out.npz")
    assert "wrote 4 smpl22 motions at 20 fps, source 'mdm' (unknown); 4 with prompts" in output
    assert [m.text for m in npz.load(tmp_path / "out.npz")] == PROMPTS


def test_import_motions_auto_says_what_it_found_and_reports_skipped_files(tmp_path):
    folder = tmp_path / "joints"
    folder.mkdir()
    for name in ("a", "b"):
        np.save(folder / f"{name}.npy", walking(6))
    np.save(folder / "c.npy", np.zeros((6, 22, 2)))
    output, errors = run(folder, "--format", "auto", "--source", "t2m_gpt", "--out",
                         tmp_path / "out.npz")
    assert "detected format 'joints'" in output and "skipped 1" in output
    assert "c.npy: an array of shape (6, 22, 2), which no format has; pass --format" in errors
    assert len(npz.load(tmp_path / "out.npz")) == 2


@pytest.mark.parametrize("args, expected", [
    (["--format", "joints", "--classes", "c.npy"], "--classes is not an option of --format joints"),
    (["--format", "mdm", "--gender", "male"], "--gender is not an option of --format mdm "
                                              r"\(it is for amass, smplx\)"),
])
def test_import_motions_refuses_flags_of_other_formats(tmp_path, args, expected):
    with pytest.raises(CommandError, match=expected):
        run(tmp_path, *args, "--out", tmp_path / "out.npz")
