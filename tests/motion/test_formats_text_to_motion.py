"""Text-to-motion codebases' outputs: MDM, HumanML3D joints and features, joint folders, auto.

Every fixture is written by the test in the exact layout the codebase writes.
"""

import numpy as np
import pytest

from motion.formats import FormatError, get_format, load_motions
from motion.formats.auto import detect
from motion.formats.humanml3d_vec import qinv, qrot, recover_from_ric
from tests.motion.body_model_files import rest_joints

PROMPTS = ["a person walks forward", "a person jumps", "someone waves", "a man sits down"]


def walking(frames=12, n_joints=22, seed=0, scale=1.0):
    """Return joints (T, J, 3), y up: SMPL's rest pose drifting forward with some noise."""
    rng = np.random.default_rng(seed)
    body = rest_joints(24)[:n_joints] if n_joints <= 24 else rest_joints(n_joints)
    drift = np.zeros((frames, 1, 3))
    drift[:, 0, 2] = np.linspace(0, 0.5, frames)
    return ((body[None] + drift + rng.normal(scale=0.005, size=(frames, n_joints, 3)))
            * scale).astype(np.float32)


def write_results(path, count=4, frames=12, n_joints=22, texts=PROMPTS, lengths=None,
                  repetitions=1, **extra):
    """Write MDM's results.npy: motion (N, J, 3, T), text, lengths, num_samples, num_repetitions."""
    motion = np.stack([walking(frames, n_joints, seed=i) for i in range(count)]).transpose(0, 2, 3, 1)
    data = {"motion": motion, "text": list(texts)[:count],
            "lengths": np.array(lengths if lengths is not None else [frames - i for i in range(count)]),
            "num_samples": count // repetitions, "num_repetitions": repetitions, **extra}
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, data)
    return motion


# --- mdm ---------------------------------------------------------------------------------


def test_mdm_results_become_smpl22_motions_with_prompts_and_lengths(tmp_path):
    motion = write_results(tmp_path / "results.npy", count=4, repetitions=2,
                           texts=PROMPTS[:2] * 2)
    motions = get_format("mdm").load(tmp_path / "results.npy")
    assert [m.skeleton for m in motions] == ["smpl22"] * 4
    assert [m.text for m in motions] == PROMPTS[:2] * 2
    assert [m.frames for m in motions] == [12, 11, 10, 9]
    assert all(m.fps == 20.0 and m.source == "mdm" and m.action == "unknown" for m in motions)
    assert [(m.meta["sample"], m.meta["repetition"]) for m in motions] == [(0, 0), (1, 0),
                                                                           (0, 1), (1, 1)]
    np.testing.assert_allclose(motions[2].joints, motion[2].transpose(2, 0, 1)[:10])


def test_mdm_kit_is_kit21_at_12_5_fps_and_action_models_are_smpl24_upright(tmp_path):
    write_results(tmp_path / "kit" / "results.npy", count=2, n_joints=21)
    kit = load_motions(tmp_path / "kit" / "results.npy", "mdm")
    assert kit[0].skeleton == "kit21" and kit[0].fps == 12.5
    # Action models write SMPL's 24 joints y down, and their action names as text.
    motion = np.stack([walking(8, 24, seed=i) * [1, -1, -1] for i in range(2)]).transpose(0, 2, 3, 1)
    np.save(tmp_path / "a2m.npy", {"motion": motion, "text": ["jump", "walk"],
                                   "lengths": np.array([8, 8]), "num_samples": 2,
                                   "num_repetitions": 1})
    jump, walk = load_motions(tmp_path / "a2m.npy", "mdm")
    assert (jump.skeleton, jump.action, jump.text, walk.action) == ("smpl24", "jump", None, "walk")
    assert (jump.joints[:, 15, 1] > jump.joints[:, 7, 1]).all(), "the head is above the ankles"


def test_mdm_smpl_params_take_joints_and_prompt_from_results_beside(tmp_path):
    write_results(tmp_path / "results.npy", count=2, repetitions=1)
    length = 10
    vertices = np.random.default_rng(0).normal(size=(30, 3, length)).astype(np.float32)
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    np.save(tmp_path / "sample01_rep00_smpl_params.npy", {
        "motion": np.zeros((25, 6, length)), "thetas": np.zeros((24, 6, length)),
        "root_translation": np.zeros((3, length)), "vertices": vertices, "faces": faces,
        "text": PROMPTS[0], "length": length})
    [mesh] = load_motions(tmp_path / "sample01_rep00_smpl_params.npy", "mdm")
    [_, joints] = load_motions(tmp_path / "results.npy", "mdm")
    assert mesh.has_body and mesh.vertices.shape == (length, 30, 3)
    assert mesh.text == PROMPTS[1], "the prompt of sample 1, not the file's first-sample text"
    np.testing.assert_allclose(mesh.joints, joints.joints[:length])
    np.testing.assert_array_equal(mesh.faces, faces)
    # Without results.npy beside it the joints need the SMPL model, which is not there.
    (tmp_path / "results.npy").unlink()
    with pytest.raises(FormatError, match="results.npy beside it .*SMPL_NEUTRAL.pkl"):
        load_motions(tmp_path / "sample01_rep00_smpl_params.npy", "mdm")


@pytest.mark.parametrize("change, expected", [
    ({"motion": np.zeros((2, 22, 12))}, r"motion has shape \(2, 22, 12\).*expected \(N, J, 3, T\)"),
    ({"lengths": np.array([12, 40])}, r"lengths\[1\] is 40, but the arrays hold 12 frames"),
    ({"text": ["only one"]}, "text has 1 entries for 2 motions"),
    ({"motion": np.zeros((2, 19, 3, 12))}, "19 joints per frame; this format knows"),
])
def test_mdm_bad_results_name_the_key_shape_and_layout(tmp_path, change, expected):
    data = {"motion": np.zeros((2, 22, 3, 12)), "text": PROMPTS[:2], "lengths": np.array([12, 12]),
            "num_samples": 2, "num_repetitions": 1, **change}
    np.save(tmp_path / "results.npy", data)
    with pytest.raises(FormatError, match="results.npy") as error:
        load_motions(tmp_path / "results.npy", "mdm")
    assert error.match(expected)


def test_mdm_wrong_key_and_nan_motions(tmp_path):
    np.save(tmp_path / "results.npy", {"poses": np.zeros(3)})
    with pytest.raises(FormatError, match=r"no key 'motion' \(keys: 'poses'\); expected MDM"):
        load_motions(tmp_path / "results.npy", "mdm")
    write_results(tmp_path / "results.npy", count=3)
    data = np.load(tmp_path / "results.npy", allow_pickle=True).item()
    data["motion"][1, 3, 0, 2] = np.nan
    np.save(tmp_path / "results.npy", data)
    motions = load_motions(tmp_path / "results.npy", "mdm")
    assert [m.text for m in motions] == [PROMPTS[0], PROMPTS[2]], "the good motions are kept"
    assert "motion 1 (a person jumps) has 1 NaN or infinite" in motions.problems[0]


# --- humanml3d ---------------------------------------------------------------------------


def write_humanml3d(root, ids=("000001", "000002"), folder="new_joints", arrays=None):
    (root / folder).mkdir(parents=True, exist_ok=True)
    (root / "texts").mkdir(exist_ok=True)
    for number, name in enumerate(ids):
        array = arrays[number] if arrays is not None else walking(10 + number, seed=number)
        np.save(root / folder / f"{name}.npy", array)
        (root / "texts" / f"{name}.txt").write_text(
            f"{PROMPTS[number]}#a/DET person/NOUN#0.0#0.0\n"
            f"the second caption of {name}#the/DET#0.5#1.5\n")


def test_humanml3d_joints_carry_their_first_whole_clip_caption(tmp_path):
    write_humanml3d(tmp_path)
    for path in (tmp_path, tmp_path / "new_joints", tmp_path / "new_joints" / "000002.npy"):
        motions = load_motions(path, "humanml3d")
        assert motions[-1].text == PROMPTS[1] and motions[-1].skeleton == "smpl22"
        assert motions[-1].meta["captions"][1] == ("the second caption of 000002", 0.5, 1.5)
    assert [m.frames for m in load_motions(tmp_path, "humanml3d")] == [10, 11]


def test_humanml3d_bad_file_is_reported_and_the_others_load(tmp_path):
    write_humanml3d(tmp_path, ids=("000001", "000002", "000003"))
    np.save(tmp_path / "new_joints" / "000002.npy", np.zeros((10, 22)))
    bad = walking(10)
    bad[4, 2, 1] = np.inf
    np.save(tmp_path / "new_joints" / "000003.npy", bad)
    motions = load_motions(tmp_path, "humanml3d")
    assert [m.meta["id"] for m in motions] == ["000001"]
    assert "000002.npy: joints has shape (10, 22)" in motions.problems[0]
    assert "000003.npy: joints holds 1 NaN or infinite values" in motions.problems[1]


def encode(joints):
    """Return HumanML3D features (T, 12 J - 1) of joints (T, J, 3) facing +z, from the layout's
    definition: root rotation velocity, root linear velocity (x, z) turned by the root's
    heading, root height, then the joints relative to the root without its heading."""
    frames, count = joints.shape[:2]
    angle = np.linspace(0, 0.6, frames)  # the root's heading turns steadily
    quaternion = np.stack([np.cos(angle), 0 * angle, np.sin(angle), 0 * angle], axis=-1)
    world = qrot(np.broadcast_to(qinv(quaternion)[:, None], (frames, count, 4)),
                 joints - joints[:, :1] * [1, 0, 1]) + joints[:, :1] * [1, 0, 1]
    features = np.zeros((frames, 12 * count - 1))
    features[:-1, 0] = np.diff(angle)
    features[:-1, 1:3] = qrot(quaternion[1:], np.diff(joints[:, 0], axis=0))[:, [0, 2]]
    features[:, 3] = joints[:, 0, 1]
    local = joints[:, 1:] - joints[:, :1] * [1, 0, 1]
    features[:, 4:4 + (count - 1) * 3] = local.reshape(frames, -1)
    return features, world


def test_recover_from_ric_inverts_the_features():
    joints = walking(15).astype(np.float64)
    joints[:, :, [0, 2]] -= joints[:1, :1, [0, 2]]  # the root starts at the origin
    features, world = encode(joints)
    np.testing.assert_allclose(recover_from_ric(features, 22), world, atol=1e-6)


def test_humanml3d_vec_denormalises_with_mean_and_std(tmp_path):
    joints = walking(15).astype(np.float64)
    joints[:, :, [0, 2]] -= joints[:1, :1, [0, 2]]
    features, world = encode(joints)
    mean, std = np.full(263, 0.5), np.full(263, 2.0)
    write_humanml3d(tmp_path, ids=("000001",), folder="new_joint_vecs",
                    arrays=[((features - mean) / std).astype(np.float32)])
    np.save(tmp_path / "Mean.npy", mean)
    np.save(tmp_path / "Std.npy", std)
    [motion] = load_motions(tmp_path, "humanml3d_vec", mean=tmp_path / "Mean.npy",
                            std=tmp_path / "Std.npy", source="momask")
    np.testing.assert_allclose(motion.joints, world, atol=1e-5)
    assert motion.text == PROMPTS[0] and motion.source == "momask"
    with pytest.raises(FormatError, match=r"Std.npy: std has shape \(263,\)|expected \(251,\)"):
        np.save(tmp_path / "new_joint_vecs" / "000001.npy", np.zeros((5, 251)))
        load_motions(tmp_path, "humanml3d_vec", mean=tmp_path / "Mean.npy",
                     std=tmp_path / "Std.npy")


# --- joints ------------------------------------------------------------------------------


def test_joints_momask_layout_takes_prompt_k_for_sample_k(tmp_path):
    for k in range(3):
        for r in range(2):
            folder = tmp_path / "joints" / str(k)
            folder.mkdir(parents=True, exist_ok=True)
            np.save(folder / f"sample{k}_repeat{r}_len12.npy", walking(12, seed=k))
    (tmp_path / "prompts.txt").write_text("\n".join(f"{p}#12" for p in PROMPTS[:3]) + "\n")
    motions = load_motions(tmp_path / "joints", "joints", texts=tmp_path / "prompts.txt",
                           source="momask")
    assert [m.text for m in motions] == [p for p in PROMPTS[:3] for _ in range(2)]
    assert motions[0].skeleton == "smpl22" and motions[0].fps == 20.0


def test_joints_t2m_gpt_batches_csv_prompts_and_kit(tmp_path):
    np.save(tmp_path / "walk.npy", walking(9)[None])  # T2M-GPT: (1, T, 22, 3)
    np.save(tmp_path / "jump.npy", walking(7, seed=1))
    (tmp_path / "prompts.csv").write_text(f"file,text\nwalk.npy,{PROMPTS[0]}\njump,{PROMPTS[1]}\n")
    jump, walk = load_motions(tmp_path, "joints")
    assert (walk.text, walk.frames, jump.text) == (PROMPTS[0], 9, PROMPTS[1])
    kit = tmp_path / "kit"
    kit.mkdir()
    np.save(kit / "a.npy", walking(5, 21, scale=1000.0))
    [motion] = load_motions(kit, "joints", file_fps=10)
    assert motion.skeleton == "kit21" and motion.fps == 10 and motion.text is None


def test_joints_bad_inputs(tmp_path):
    for name in ("a", "b", "c"):
        np.save(tmp_path / f"{name}.npy", walking(6))
    (tmp_path / "prompts.txt").write_text("one\ntwo\n")
    with pytest.raises(FormatError, match="2 prompts for 3 motion files"):
        load_motions(tmp_path, "joints")
    (tmp_path / "prompts.txt").unlink()
    with pytest.raises(FormatError, match="skeleton 'kit21' has 21 joints"):
        load_motions(tmp_path / "a.npy", "joints", skeleton="kit21")
    np.save(tmp_path / "b.npy", np.full((6, 22, 3), np.nan))
    np.save(tmp_path / "c.npy", np.zeros((6, 22, 2)))
    motions = load_motions(tmp_path, "joints")
    assert len(motions) == 1 and len(motions.problems) == 2
    assert "b.npy: joints holds 396 NaN" in motions.problems[0]
    assert "c.npy: joints has shape (6, 22, 2)" in motions.problems[1]


# --- auto --------------------------------------------------------------------------------


def test_auto_detects_each_format_and_says_so(tmp_path):
    write_results(tmp_path / "mdm" / "results.npy", count=2)
    write_humanml3d(tmp_path / "hml")
    np.save(tmp_path / "one.npy", walking(6))
    np.save(tmp_path / "vec.npy", np.zeros((6, 263)))
    np.save(tmp_path / "actor.npy", np.zeros((1, 2, 10, 3, 4)))
    np.savez(tmp_path / "amass.npz", poses=np.zeros((3, 156)), trans=np.zeros((3, 3)))
    np.savez(tmp_path / "critic.npz", {"prompt": ["a"], "motion": [np.zeros((1, 25, 6, 60))]})
    expected = {"mdm/results.npy": "mdm", "hml": "humanml3d", "hml/new_joints": "humanml3d",
                "one.npy": "joints", "vec.npy": "humanml3d_vec", "actor.npy": "actor",
                "amass.npz": "amass", "critic.npz": "motioncritic"}
    for name, fmt in expected.items():
        assert detect(tmp_path / name)[0] == fmt, name
    motions = load_motions(tmp_path / "mdm", "auto")
    assert len(motions) == 2 and "detected format 'mdm'" in motions.notes[0]
    with pytest.raises(FormatError, match="cannot tell the format of a .txt file"):
        detect(tmp_path / "hml" / "texts" / "000001.txt")
