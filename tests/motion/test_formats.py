"""Imports of external motions: Action2Motion arrays, BVH files, and the import_motions command."""

import io
from pathlib import Path

import numpy as np
import pytest
from django.core.management import CommandError, call_command

from motion.datasets.humanact12 import CLASSES
from motion.formats import FormatError, a2m, bvh, list_formats, load_motions, npz
from tests.conftest import make_motion

FIXTURE = Path(__file__).parent / "data" / "cmu_walk.bvh"
CMU_UNIT = 0.0254 / 0.45
ROOT = np.array([0.5, 16.0, -1.0])  # the fixture's root position in frames 0-2 (file units)
# Offsets from Hips down to LeftHand in the fixture: LowerBack, Spine, Spine1, LeftShoulder,
# LeftArm, LeftForeArm, LeftHand.
LEFT_ARM_CHAIN = [(0, 0, 0), (0.02, 2.2, -0.1), (0.03, 2.2, -0.15), (0, 0, 0), (3.2, 0.9, 0.05),
                  (5.0, 0, 0), (3.4, 0, 0)]


ROOT_CHANNELS = "Xposition Yposition Zposition Zrotation Yrotation Xrotation"


def write_bvh(path, joints, frames, channels=ROOT_CHANNELS):
    """Write a BVH of ``joints`` [(name, parent index, offset)] whose root has ``channels``
    and the others three rotations; ``frames`` are rows of channel values."""
    lines = ["HIERARCHY"]
    children = {}
    for index, (_, parent, _) in enumerate(joints):
        children.setdefault(parent, []).append(index)

    def block(index, depth):
        name, parent, offset = joints[index]
        tab = "  " * depth
        lines.append(f"{tab}{'ROOT' if parent < 0 else 'JOINT'} {name}")
        lines.append(f"{tab}{{")
        lines.append(f"{tab}  OFFSET {offset[0]} {offset[1]} {offset[2]}")
        count = len(channels.split()) if parent < 0 else 3
        lines.append(f"{tab}  CHANNELS {count} "
                     f"{channels if parent < 0 else 'Zrotation Yrotation Xrotation'}")
        for child in children.get(index, []):
            block(child, depth + 1)
        if index not in children:
            lines.extend([f"{tab}  End Site", f"{tab}  {{", f"{tab}    OFFSET 0 1 0", f"{tab}  }}"])
        lines.append(f"{tab}}}")

    block(0, 0)
    lines += ["MOTION", f"Frames: {len(frames)}", "Frame Time: 0.0333333"]
    lines += [" ".join(str(v) for v in row) for row in frames]
    path.write_text("\n".join(lines) + "\n")
    return path


# --- Action2Motion ---------------------------------------------------------------------


def write_a2m(tmp_path, n=5, frames=6, n_joints=24, seed=0):
    rng = np.random.default_rng(seed)
    joints = rng.normal(size=(n, frames, n_joints * 3)).astype(np.float32)
    classes = np.arange(n) % 12
    np.save(tmp_path / "motions.npy", joints)
    np.save(tmp_path / "classes.npy", classes)
    return tmp_path / "motions.npy", tmp_path / "classes.npy", joints, classes


def test_a2m_round_trip_keeps_joints_and_names_classes(tmp_path):
    path, classes_path, joints, classes = write_a2m(tmp_path)
    motions = a2m.load(path, classes_path)
    assert len(motions) == 5
    assert all(m.skeleton == "humanact12" and m.fps == 20.0 and m.source == "a2m" for m in motions)
    for motion, flat, k in zip(motions, joints, classes):
        np.testing.assert_array_equal(motion.joints, flat.reshape(6, 24, 3))
        assert motion.action == CLASSES[k]
    assert motions[3].meta == {"file": str(path), "index": 3, "class": 3}


def test_a2m_17_joints_is_h36m17_with_numbered_classes_or_given_names(tmp_path):
    path, classes_path, _, _ = write_a2m(tmp_path, n=3, n_joints=17)
    motions = a2m.load(path, classes_path)
    assert [m.skeleton for m in motions] == ["h36m17"] * 3
    assert [m.action for m in motions] == ["class0", "class1", "class2"]
    assert motions[0].fps == 25.0
    named = a2m.load(path, classes_path, file_fps=50, action_names=["Walking", "Eating", "Sitting"])
    assert [m.action for m in named] == ["Walking", "Eating", "Sitting"] and named[0].fps == 50


@pytest.mark.parametrize("shape, expected", [
    ((4, 6, 70), "expected (N, T, J*3)"),
    ((4, 6, 30), "10 joints per frame; this format knows"),
    ((6, 72), "expected (N, T, J*3)"),
])
def test_a2m_wrong_joint_shapes_say_what_is_expected(tmp_path, shape, expected):
    np.save(tmp_path / "bad.npy", np.zeros(shape, np.float32))
    np.save(tmp_path / "classes.npy", np.zeros(shape[0], np.int64))
    with pytest.raises(FormatError, match="bad.npy") as error:
        a2m.load(tmp_path / "bad.npy", tmp_path / "classes.npy")
    assert str(shape) in str(error.value) and expected in str(error.value)


def test_a2m_class_errors_name_the_class_file(tmp_path):
    path, classes_path, _, _ = write_a2m(tmp_path)
    np.save(classes_path, np.zeros(4, np.int64))
    with pytest.raises(FormatError,
                       match=r"classes.npy: class indices of shape \(4,\); expected \(5,\)"):
        a2m.load(path, classes_path)
    np.save(classes_path, np.array([0, 1, 2, 3, 12]))
    with pytest.raises(FormatError, match="class index 12 but 12 action names"):
        a2m.load(path, classes_path)
    with pytest.raises(FormatError, match="skeleton 'h36m17' has 17 joints"):
        a2m.load(path, classes_path, skeleton="h36m17")
    with pytest.raises(FormatError, match="nothing.npy does not exist"):
        a2m.load(tmp_path / "nothing.npy", classes_path)


# --- BVH -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fixture_units():
    """The fixture read in its own units (scale 1)."""
    return bvh.read(FIXTURE, scale=1.0)


def test_bvh_fixture_parses(fixture_units):
    motion = fixture_units
    assert motion.frames == 8 and motion.fps == 120.0
    assert motion.n_joints == 38 and len(motion.end_sites) == 7  # 31 joints, as CMU's
    assert motion.joint_names[:3] == ("Hips", "LHipJoint", "LeftUpLeg")
    index = motion.joint_names.index
    assert motion.parents[index("LeftLeg")] == index("LeftUpLeg")
    assert "Head_End" in motion.joint_names


def test_bvh_forward_kinematics_of_an_offset_chain(fixture_units):
    hand = fixture_units.joint_names.index("LeftHand")
    forearm = fixture_units.joint_names.index("LeftForeArm")
    chain = np.sum(LEFT_ARM_CHAIN, axis=0)
    positions = fixture_units.positions.astype(np.float64)
    # Frame 0: every rotation zero, the root translated.
    np.testing.assert_allclose(positions[0, 0], ROOT, atol=1e-5)
    np.testing.assert_allclose(positions[0, hand], ROOT + chain, atol=1e-5)
    # Frame 1: the root turned 90 degrees about y: (x, y, z) -> (z, y, -x).
    turned = [chain[2], chain[1], -chain[0]]
    np.testing.assert_allclose(positions[1, hand], ROOT + turned, atol=1e-4)
    # Frame 2: LeftForeArm turned 90 degrees about z: the hand's offset (3.4, 0, 0) points up.
    np.testing.assert_allclose(positions[2, hand], positions[0, forearm] + [0, 3.4, 0], atol=1e-4)


@pytest.mark.parametrize("order, expected", [
    ("Xrotation Yrotation", [0.0, 1.0, 0.0]),  # Rx(90) @ Ry(90) @ (1, 0, 0)
    ("Yrotation Xrotation", [0.0, 0.0, -1.0]),  # Ry(90) @ Rx(90) @ (1, 0, 0)
])
def test_bvh_rotation_channels_apply_in_the_listed_order(tmp_path, order, expected):
    path = write_bvh(tmp_path / "order.bvh", [("Root", -1, (0, 0, 0)), ("Child", 0, (1, 0, 0))],
                     [[90, 90, 0, 0, 0, 0, 0, 0]],
                     channels=f"{order} Xposition Yposition Zposition")
    motion = bvh.read(path, scale=1.0)
    np.testing.assert_allclose(motion.positions[0, 1], expected, atol=1e-6)


def test_bvh_scale_is_guessed_from_the_body_size_or_given():
    assert bvh.read(FIXTURE).scale == pytest.approx(CMU_UNIT)
    assert bvh.read(FIXTURE, scale="cm").scale == 0.01
    units = bvh.read(FIXTURE, scale=1.0)
    np.testing.assert_allclose(bvh.read(FIXTURE).positions, units.positions * CMU_UNIT, rtol=1e-5)
    assert bvh.guess_scale(np.array([[0, 0, 0], [0, 175, 0]])) == 0.01
    assert bvh.guess_scale(np.array([[0, 0, 0], [0, 1.8, 0]])) == 1.0


def test_bvh_to_h36m17_is_z_up_with_a_plausible_height():
    motion = bvh.to_skeleton(bvh.read(FIXTURE), "h36m17", action="walk")
    assert motion.joints.shape == (8, 17, 3) and motion.fps == 120.0 and motion.action == "walk"
    names = motion.meta["bvh_joints"]
    assert names["Hip"] == "Hips" and names["Head"] == "Head_End" and names["LWrist"] == "LeftHand"
    first = motion.joints[0]
    head, foot, hip = first[10], first[[3, 6]].mean(axis=0), first[0]
    assert 1.2 < head[2] - foot[2] < 2.0
    assert foot[2] < hip[2] < head[2]
    # y up becomes z up: the height in the file (y) is z here.
    np.testing.assert_allclose(hip, np.array([0.5, 1.0, 16.0]) * CMU_UNIT, atol=1e-5)


def test_bvh_to_humanact12_stays_y_up():
    source = bvh.read(FIXTURE)
    motion = bvh.to_skeleton(source, "humanact12", action="walk")
    assert motion.joints.shape == (8, 24, 3)
    np.testing.assert_allclose(motion.joints[:, 0], source.positions[:, 0])
    assert motion.joints[0, 15, 1] > motion.joints[0, 0, 1] > motion.joints[0, 7, 1]


def test_bvh_mixamo_prefixes_and_names_map(tmp_path):
    text = FIXTURE.read_text()
    for keyword in ("ROOT ", "JOINT "):
        text = text.replace(keyword, keyword + "mixamorig:")
    prefixed = tmp_path / "prefixed.bvh"
    prefixed.write_text(text)
    motion = bvh.to_skeleton(bvh.read(prefixed), "h36m17")
    assert motion.meta["bvh_joints"]["Hip"] == "mixamorig:Hips"
    np.testing.assert_allclose(motion.joints, bvh.to_skeleton(bvh.read(FIXTURE), "h36m17").joints)

    names = ["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head", "HeadTop_End"]
    joints = [(f"mixamorig:{name}", i - 1, (0, 10, 0)) for i, name in enumerate(names)]
    for side, sign in (("Left", 1), ("Right", -1)):
        joints += [(f"mixamorig:{side}UpLeg", 0, (sign * 10, -5, 0)),
                   (f"mixamorig:{side}Leg", len(joints), (0, -40, 0)),
                   (f"mixamorig:{side}Foot", len(joints) + 1, (0, -40, 0)),
                   (f"mixamorig:{side}Arm", 3, (sign * 15, 5, 0)),
                   (f"mixamorig:{side}ForeArm", len(joints) + 3, (sign * 25, 0, 0)),
                   (f"mixamorig:{side}Hand", len(joints) + 4, (sign * 25, 0, 0))]
    path = write_bvh(tmp_path / "mixamo.bvh", joints, [[0.0] * (6 + 3 * (len(joints) - 1))] * 2)
    mixamo = bvh.read(path)
    assert mixamo.scale == 0.01
    motion = bvh.to_skeleton(mixamo, "h36m17")
    assert motion.meta["bvh_joints"]["Spine"] == "mixamorig:Spine1"
    assert motion.meta["bvh_joints"]["Head"] == "mixamorig:HeadTop_End"


def test_bvh_unmappable_joints_are_listed_with_the_files_joints(tmp_path):
    path = write_bvh(tmp_path / "odd.bvh", [("Pelvis", -1, (0, 90, 0)), ("Chest", 0, (0, 40, 0)),
                                            ("Skull", 1, (0, 30, 0))], [[0.0] * 12])
    with pytest.raises(bvh.BvhError) as error:
        bvh.to_skeleton(bvh.read(path), "h36m17")
    message = str(error.value)
    assert "odd.bvh" in message and "RKnee (from 'RightLeg')" in message
    assert "Pelvis, Chest, Skull" in message and "mapping=" in message and "--joint-map" in message
    mapping = {name: "Chest" for name in ("RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot",
                                          "Thorax", "LShoulder", "LElbow", "LWrist", "RShoulder",
                                          "RElbow", "RWrist")}
    mapping.update({"Hip": "Pelvis", "Spine": "Chest", "Neck/Nose": "Skull", "Head": "Skull_End"})
    motion = bvh.to_skeleton(bvh.read(path), "h36m17", mapping=mapping)
    assert motion.meta["bvh_joints"]["Hip"] == "Pelvis"
    with pytest.raises(bvh.BvhError, match="Toe, which are not joints of h36m17"):
        bvh.to_skeleton(bvh.read(path), "h36m17", mapping={"Toe": "Skull"})


@pytest.mark.parametrize("damage, expected", [
    (lambda t: t.replace("Frames: 8", "Frames: 9"),
     r"expected Frames \(9\) x channels in HIERARCHY \(96\)"),
    (lambda t: t.replace("Xrotation\n", "Wrotation\n", 1), "channels are Xposition"),
    (lambda t: t.replace("MOTION", "MOTIONS"), "no MOTION section"),
    (lambda t: t.replace("OFFSET 1.60000 -1.80000 0.80000", "OFFSET 1.6 -1.8"),
     "line 12: OFFSET needs 3 numbers"),
    (lambda t: "\n".join(t.split("\n")[:-3]) + "\n", "MOTION holds"),
])
def test_bvh_malformed_files_say_where(tmp_path, damage, expected):
    path = tmp_path / "broken.bvh"
    path.write_text(damage(FIXTURE.read_text()))
    with pytest.raises(bvh.BvhError, match=expected):
        bvh.read(path)


def test_bvh_up_rotation():
    np.testing.assert_allclose(bvh.up_rotation("y", "z") @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(bvh.up_rotation("y", "z") @ [0, 0, 1], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(bvh.up_rotation("z", "y") @ [0, 0, 1], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(bvh.up_rotation("y", "-y") @ [0, 1, 0], [0, -1, 0], atol=1e-12)
    for source, target in (("y", "z"), ("z", "y"), ("x", "-y"), ("y", "-y")):
        rotation = bvh.up_rotation(source, target)
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rotation) == pytest.approx(1.0)


# --- one entry point -------------------------------------------------------------------


def test_load_motions_dispatches_resamples_and_relabels(tmp_path):
    assert {"a2m", "bvh", "npz", "mdm", "humanml3d", "humanml3d_vec", "joints", "amass",
            "motioncritic", "actor", "auto", "wham", "phalp", "vibe", "tram", "aistpp", "phc",
            "amp_poselib"} <= set(list_formats())
    path, classes_path, _, _ = write_a2m(tmp_path)
    motions = load_motions(path, "a2m", classes_path=classes_path, fps=10, source="theirs")
    assert len(motions) == 5 and motions[0].fps == 10 and motions[0].source == "theirs"
    assert motions[0].frames == 3
    [walk] = load_motions(FIXTURE, "bvh", skeleton="humanact12", action="walk")
    assert walk.skeleton == "humanact12" and walk.source == "real"
    with pytest.raises(FormatError, match="unknown motion format 'fbx'"):
        load_motions(FIXTURE, "fbx")
    with pytest.raises(FormatError,
                       match="takes options skeleton, action, mapping, scale, up, texts, source; "
                             "got fps_"):
        load_motions(FIXTURE, "bvh", fps_=3)


# --- the import_motions command --------------------------------------------------------


def run(*args):
    output = io.StringIO()
    call_command("import_motions", *map(str, args), stdout=output)
    return output.getvalue()


def test_import_motions_npz_rewrites_with_a_new_source_and_rate(tmp_path):
    original = [make_motion(frames=9, seed=i, action=a) for i, a in enumerate(["walk", "sit"])]
    npz.save(tmp_path / "in.npz", original)
    output = run(tmp_path / "in.npz", "--format", "npz", "--source", "theirs", "--fps", "12.5",
                 "--out", tmp_path / "out.npz")
    assert "wrote 2 h36m17 motions at 12.5 fps, source 'theirs'" in output
    motions = npz.load(tmp_path / "out.npz")
    assert [m.action for m in motions] == ["walk", "sit"] and motions[0].frames == 5
    np.testing.assert_allclose(motions[0].joints[1], original[0].joints[2], atol=1e-6)


def test_import_motions_a2m(tmp_path):
    path, classes_path, joints, _ = write_a2m(tmp_path)
    run(path, "--format", "a2m", "--classes", classes_path, "--out", tmp_path / "out.npz")
    motions = npz.load(tmp_path / "out.npz")
    assert [m.action for m in motions] == list(CLASSES[:5]) and motions[0].source == "a2m"
    np.testing.assert_array_equal(motions[4].joints, joints[4].reshape(6, 24, 3))


def test_import_motions_bvh_files(tmp_path):
    second = tmp_path / "second.bvh"
    second.write_text(FIXTURE.read_text())
    output = run(FIXTURE, second, "--format", "bvh", "--skeleton", "h36m17", "--action", "walk",
                 "--fps", "30", "--out", tmp_path / "out.npz")
    assert "wrote 2 h36m17 motions at 30 fps, source 'real' (walk)" in output
    motions = npz.load(tmp_path / "out.npz")
    assert len(motions) == 2 and motions[0].frames == 2 and motions[0].skeleton == "h36m17"


@pytest.mark.parametrize("args, expected", [
    (["--format", "bvh", "--skeleton", "h36m17", "--action", "walk", "--classes", "c.npy"],
     "--classes is not an option of --format bvh \\(it is for a2m\\)"),
    (["--format", "a2m"], "need their class indices; pass classes_path"),
    (["--format", "bvh", "--skeleton", "h36m17", "--action", "walk", "--joint-map", "Spine"],
     "write JOINT=BVH_JOINT pairs"),
    (["--format", "bvh", "--skeleton", "h36m17", "--action", "walk", "--joint-map", "Spine=Nope"],
     "cannot map these h36m17 joints: Spine"),
    (["--format", "npz"], "is not a readable .npz file"),
])
def test_import_motions_user_mistakes(tmp_path, args, expected):
    with pytest.raises(CommandError, match=expected):
        run(FIXTURE, *args, "--out", tmp_path / "out.npz")
    assert not (tmp_path / "out.npz").exists()
