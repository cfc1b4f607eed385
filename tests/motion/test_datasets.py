"""Datasets: the synthetic demo, Human3.6M (both layouts, 3D and 2D), HumanAct12, the command."""

import io
import json

import numpy as np
import pytest
from django.core.management import CommandError, call_command

from motion.datasets import DatasetError, get_dataset, list_datasets
from motion.datasets.cameras import load_cameras
from motion.datasets.synthetic import ACTIONS, generate
from motion.datasets.h36m import H36M, action_of
from motion.datasets.h36m2d import H36M2D
from motion.datasets.humanact12 import HumanAct12
from motion.skeletons import H36M17, H36M32_TO_17


def test_every_dataset_is_registered():
    assert {"demo", "h36m", "h36m2d", "humanact12"} <= set(list_datasets())


# --- demo ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def demo_takes():
    return get_dataset("demo").load_takes().motions


def test_demo_has_eight_synthetic_actions(demo_takes):
    demo = get_dataset("demo")
    assert demo.synthetic and demo.subjects is None
    assert demo.actions() == ["walk", "run", "jump", "wave", "squat", "kick", "throw", "sit_down"]
    assert {m.action for m in demo_takes} == set(ACTIONS)
    assert all(m.skeleton == "h36m17" and m.fps == 25 and m.meta["synthetic"] for m in demo_takes)


def test_demo_bone_lengths_are_constant_within_a_take(demo_takes):
    for motion in demo_takes:
        lengths = H36M17.bone_lengths(motion.joints.astype(np.float64))
        assert lengths.std(axis=0).max() < 1e-5, motion.meta["take"]


def test_demo_feet_are_on_the_ground(demo_takes):
    feet = [H36M17.index("RFoot"), H36M17.index("LFoot")]
    for motion in demo_takes:
        lowest = motion.joints[:, feet, 2].min(axis=1)
        assert lowest.min() > -1e-4 and np.median(lowest) < 0.01, motion.meta["take"]
        assert motion.joints[:, H36M17.index("Head"), 2].min() > 0.5


def test_demo_walkers_move_forward_and_others_stay(demo_takes):
    def travel(motion):
        return np.linalg.norm(motion.joints[-1, 0, :2] - motion.joints[0, 0, :2])

    assert min(travel(m) for m in demo_takes if m.action in ("walk", "run")) > 2.0
    assert max(travel(m) for m in demo_takes if m.action in ("wave", "kick")) < 0.1


def test_demo_samples_differ_in_size_and_motion(demo_takes):
    waves = [m for m in demo_takes if m.action == "wave"]
    heights = [m.joints[0, H36M17.index("Head"), 2] for m in waves]
    assert max(heights) - min(heights) > 0.15
    assert len({m.meta["side"] for m in waves}) == 2
    assert not np.allclose(waves[0].joints, waves[1].joints)


def test_demo_is_deterministic(demo_takes):
    fresh = generate.__wrapped__(0, 2, 4.0)  # bypass the cache; two takes per action
    for motion in fresh:
        same = next(m for m in demo_takes if m.meta["take"] == motion.meta["take"])
        np.testing.assert_array_equal(same.joints, motion.joints)


def test_demo_clips_follow_the_defaults_and_limits():
    demo = get_dataset("demo")
    clips = demo.clips(actions=["walk", "jump"])
    assert {c.joints.shape for c in clips} == {(60, 17, 3)}
    assert len(clips) == demo.count_clips(actions=["walk", "jump"]) == 2 * 24 * 2
    assert clips[1].meta["start_frame"] == 30 and clips[1].meta["take"] == "walk_00"
    assert len(demo.clips(max_per_take=1)) == 8 * 24
    with pytest.raises(DatasetError, match="no subjects"):
        demo.clips(subjects=["S1"])


def test_unknown_action_lists_the_valid_ones():
    with pytest.raises(DatasetError, match="'dance'.*walk, run, jump"):
        get_dataset("demo").clips(actions=["walk", "dance"])


# --- h36m from the shared compact file ------------------------------------------------------

def test_h36m_compact_subset_in_metres_z_up(h36m_root):
    report = H36M(h36m_root).load_takes(subjects=["S1"], actions=["Walking"])
    assert report.problems == []
    assert sorted(m.meta["take"] for m in report.motions) == ["Walking", "Walking 1"]
    for motion in report.motions:
        assert motion.skeleton == "h36m17" and motion.fps == 25 and motion.action == "Walking"
        assert motion.joints.shape[1:] == (17, 3) and motion.frames > 1000
        thigh = H36M17.bone_lengths(motion.joints)[:, H36M17.index("RKnee")]
        assert 0.35 < thigh.mean() < 0.55  # metres
        head, foot = (motion.joints[:, H36M17.index(j), 2].mean() for j in ("Head", "RFoot"))
        assert head - foot > 1.2  # z up


def test_h36m_subject_split_and_action_names(h36m_root):
    data = H36M(h36m_root)
    clips = data.clips(subjects=["s5"], actions=["walking", "WalkDog"], max_per_take=2)
    assert {c.meta["subject"] for c in clips} == {"S5"}
    assert {c.action for c in clips} == {"Walking", "WalkDog"}
    assert len(clips) == 8  # 2 takes per action, 2 clips each
    with pytest.raises(DatasetError, match="S2.*S1, S5, S6, S7, S8, S9, S11"):
        data.clips(subjects=["S2"])


def test_take_names_give_actions():
    assert action_of("Walking 1") == "Walking"
    assert action_of("WalkDog") == "WalkDog"
    assert action_of("WalkTogether 2") == "WalkTogether"
    assert action_of("SittingDown 1") == "SittingDown"
    assert action_of("TakingPhoto 1") == "Photo"


# --- h36m from the original h5 layout -------------------------------------------------------

def write_take(root, subject, take, frames=20, seed=0):
    """Write a 3d-pose-baseline take (96, frames) in millimetres and return it (frames, 32, 3)."""
    import h5py

    folder = root / subject / "MyPoses" / "3D_positions"
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    joints = rng.uniform(-1000, 1000, size=(frames, 32, 3)) + [0, 0, 4000]
    with h5py.File(folder / f"{take}.h5", "w") as handle:
        handle["3D_positions"] = joints.reshape(frames, 96).T
    return joints


@pytest.fixture
def h5_root(tmp_path):
    """Return a tiny original-layout tree: two good takes and one corrupt file of S1."""
    originals = {
        "Walking 1": write_take(tmp_path, "S1", "Walking 1", frames=20),
        "WalkDog": write_take(tmp_path, "S1", "WalkDog", frames=9, seed=1),
    }
    (tmp_path / "S1" / "MyPoses" / "3D_positions" / "Eating.h5").write_bytes(b"not hdf5")
    return tmp_path, originals


def test_h36m_h5_layout_converts_and_reports_a_corrupt_file(h5_root):
    root, originals = h5_root
    report = H36M(root).load_takes()
    assert len(report.problems) == 1
    assert "Eating.h5" in report.problems[0] and "(96, frames)" in report.problems[0]
    takes = {m.meta["take"]: m for m in report.motions}
    assert set(takes) == {"Walking 1", "WalkDog"}
    assert takes["WalkDog"].action == "WalkDog" and takes["WalkDog"].frames == 5
    expected = originals["Walking 1"][::2][:, list(H36M32_TO_17)] / 1000
    np.testing.assert_allclose(takes["Walking 1"].joints, expected, rtol=1e-6)
    assert H36M(root).take_lengths() == [5, 10]  # WalkDog, then Walking 1


def test_h36m_missing_root_names_path_layouts_and_fix(tmp_path):
    missing = tmp_path / "nowhere"
    with pytest.raises(DatasetError) as error:
        H36M(missing).clips()
    message = str(error.value)
    for part in (str(missing), "h36m_positions_25fps.npz", "3D_positions", "STUDY_H36M_ROOT",
                 "--data-root"):
        assert part in message


def test_h36m_root_from_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("STUDY_H36M_ROOT", str(tmp_path))
    assert H36M().data_root == tmp_path


def test_compact_file_with_a_bad_take(tmp_path):
    good = np.zeros((30, 17, 3), np.float32)
    np.savez(tmp_path / "h36m_positions_25fps.npz", **{"S1/Walking": good, "S1/Eating 1": good[:, :5]})
    report = H36M(tmp_path).load_takes()
    assert [m.meta["take"] for m in report.motions] == ["Walking"]
    assert len(report.problems) == 1 and "'S1/Eating 1'" in report.problems[0]
    assert "(30, 5, 3)" in report.problems[0]


# --- h36m2d ---------------------------------------------------------------------------------

def project_by_hand(point_mm, cam):
    """Project one point with 3d-pose-baseline's formula, written out coordinate by coordinate."""
    R, T = np.array(cam["R"]), np.array(cam["T"])
    X, Y, Z = R @ (np.asarray(point_mm, dtype=np.float64) - T)
    x, y = X / Z, Y / Z
    r2 = x * x + y * y
    k1, k2, k3 = cam["k"]
    p1, p2 = cam["p"]
    scale = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3 + p1 * y + p2 * x
    u = cam["f"][0] * (x * scale + p2 * r2) + cam["c"][0]
    v = cam["f"][1] * (y * scale + p1 * r2) + cam["c"][1]
    return np.array([u, v])


def test_h36m2d_projects_onto_camera_55011271(h36m_root):
    data = H36M2D(h36m_root)
    take_2d = data.load_takes(subjects=["S1"], actions=["Walking"]).motions[0]
    take_3d = H36M(h36m_root).load_takes(subjects=["S1"], actions=["Walking"]).motions[0]
    assert take_2d.skeleton == "h36m15_2d" and take_2d.joints.shape[1:] == (15, 2)
    assert take_2d.meta["camera"] == "55011271" and take_2d.frames == take_3d.frames
    assert 0 < take_2d.joints.min() and take_2d.joints.max() < 1000
    cam = next(c for c in json.loads((h36m_root / "cameras.json").read_text())["subjects"]["S1"]
               if c["name"] == "55011271")
    knee_3d = take_3d.joints[7, H36M17.index("RKnee")] * 1000
    np.testing.assert_allclose(take_2d.joints[7, 1], project_by_hand(knee_3d, cam), atol=1e-2)
    head_2d = take_2d.joints[:, 8, 1].mean()
    assert head_2d < take_2d.joints[:, 2, 1].mean()  # head above the foot: y points down


def test_h36m2d_clips_at_16_7_hz(h36m_root):
    data = H36M2D(h36m_root)
    assert len(data.actions()) == 10 and "WalkDog" not in data.actions()
    clips = data.clips(subjects=["S1"], actions=["Walking"])
    assert {c.joints.shape for c in clips} == {(50, 15, 2)}
    assert all(c.fps == pytest.approx(50 / 3) for c in clips)
    assert len(clips) == data.count_clips(subjects=["S1"], actions=["Walking"])
    # 1567 and 1738 frames at 25 fps -> 1045 and 1159 at 50/3, windows every 25 frames.
    assert len(clips) == (1045 - 50) // 25 + 1 + (1159 - 50) // 25 + 1


def test_h36m2d_reads_3d_pose_baseline_cameras_h5(h5_root, h36m_root):
    import h5py

    root, _ = h5_root
    cam = next(c for c in json.loads((h36m_root / "cameras.json").read_text())["subjects"]["S1"]
               if c["name"] == "55011271")
    with h5py.File(root / "cameras.h5", "w") as handle:
        group = handle.create_group("subject1/camera2")
        group["R"] = np.array(cam["R"]).T  # stored camera-to-world
        for key, shape in (("T", (3, 1)), ("f", (2, 1)), ("c", (2, 1)), ("k", (3, 1)), ("p", (2, 1))):
            group[key] = np.array(cam[key]).reshape(shape)
        group["Name"] = np.array([ord(ch) for ch in "55011271"], dtype=np.uint8)
    camera = load_cameras(root)["S1"]["55011271"]
    point = np.array([100.0, -200.0, 900.0])
    np.testing.assert_allclose(camera.project(point), project_by_hand(point, cam), atol=1e-6)
    report = H36M2D(root).load_takes(actions=["Walking", "WalkDog"])
    assert len(report.motions) == 2 and report.motions[0].joints.shape[1:] == (15, 2)


# --- humanact12 -----------------------------------------------------------------------------

@pytest.fixture
def humanact12_root(tmp_path):
    rng = np.random.default_rng(0)
    for name, frames in (("P01G01R01F0001T0064A0101", 64), ("P02G01R01F0069T0143A0102", 75),
                         ("P03G02R02F0001T0120A0201", 120)):
        np.save(tmp_path / f"{name}.npy", rng.normal(size=(frames, 24, 3)).astype(np.float32))
    np.save(tmp_path / "P01G01R01F0001T0040A0401.npy", np.zeros((40, 17, 3)))  # wrong shape
    np.save(tmp_path / "P01G01R01F0001T0040.npy", np.zeros((40, 24, 3)))  # no action code
    (tmp_path / "P01G01R01F0001T0040A1201.npy").write_bytes(b"garbage")  # unreadable
    return tmp_path


def test_humanact12_loads_good_files_and_reports_bad_ones(humanact12_root):
    data = HumanAct12(humanact12_root)
    report = data.load_takes()
    assert sorted((m.action, m.frames) for m in report.motions) == [
        ("walk", 120), ("warm_up", 64), ("warm_up", 75)]
    assert report.motions[0].meta["subject"] in {"P01", "P02", "P03"}
    assert len(report.problems) == 3
    assert any("A0401.npy" in p and "(40, 17, 3)" in p for p in report.problems)
    assert any("T0040.npy" in p and "A<4-digit action code>" in p for p in report.problems)
    assert any("A1201.npy" in p and "not a readable" in p for p in report.problems)
    clips = data.clips(actions=["warm_up"])
    assert [c.joints.shape for c in clips] == [(60, 24, 3), (60, 24, 3)]
    assert clips[0].fps == 20 and data.actions()[11] == "throw"


def test_humanact12_without_valid_files_or_root(tmp_path, monkeypatch):
    monkeypatch.delenv("STUDY_HUMANACT12_ROOT", raising=False)
    with pytest.raises(DatasetError, match="--data-root"):
        HumanAct12().load_takes()
    (tmp_path / "bad_A0101.npy").write_bytes(b"garbage")
    with pytest.raises(DatasetError, match="no valid HumanAct12 file"):
        HumanAct12(tmp_path).load_takes()


# --- the datasets command -------------------------------------------------------------------

def run_datasets(*args):
    out = io.StringIO()
    call_command("datasets", *args, stdout=out)
    return out.getvalue()


def test_datasets_command_json(monkeypatch, humanact12_root):
    monkeypatch.delenv("STUDY_HUMANACT12_ROOT", raising=False)
    listing = json.loads(run_datasets("--json"))
    assert set(listing) == set(list_datasets())
    assert listing["demo"] == {"skeleton": "h36m17", "actions": list(ACTIONS), "clips": 384}
    assert "--data-root" in listing["humanact12"]["error"]
    if "error" not in listing["h36m"]:
        assert listing["h36m"]["clips"] > 1000 and len(listing["h36m"]["actions"]) == 15
    one = json.loads(run_datasets("humanact12", "--json", "--data-root", str(humanact12_root)))
    assert one == {"humanact12": {"skeleton": "humanact12",
                                  "actions": HumanAct12().actions(), "clips": 1 + 1 + 3}}
    assert "384 clips" in run_datasets("demo")
    with pytest.raises(CommandError, match="unknown dataset"):
        run_datasets("mocap")
