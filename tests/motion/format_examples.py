"""One example file per registered format, written in its codebase's own layout, and one
malformed file each, for the formats' contract test (synthetic data; body models are the
synthetic ones of body_model_files).

``EXAMPLES[name](folder) -> (path, options)``: a file (or folder) and the options to read
it with (``body_models`` is added by the test); ``MALFORMED[name](folder) -> (path,
message)``: a file of the format's kind that is broken, and what the error must say.
"""

import importlib
import pickle
from collections import OrderedDict
from pathlib import Path

import joblib
import numpy as np

from tests.motion.bvh_layouts import write as write_bvh
from tests.motion.test_formats_smpl import rot6d_motion
from tests.motion.test_formats_text_to_motion import encode, walking, write_results

FRAMES = 6
UPSIDE_DOWN = np.array([np.pi, 0, 0])  # a camera's y-down frame
Z_UP = np.array([np.pi / 2, 0, 0])  # SMPL's y-up body turned onto z up


def smpl_poses(root=np.zeros(3), frames=FRAMES):
    """Return axis-angle poses (T, 72): the root turned by ``root``, a knee bending."""
    poses = np.zeros((frames, 72))
    poses[:, :3] = root
    poses[:, 3 * 4] = np.linspace(0, 0.6, frames)  # left knee about x
    return poses


def rotmats(poses):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(poses.reshape(-1, 3)).as_matrix().reshape(len(poses), 24, 3, 3)


def wham(folder):
    people = {}
    for person in (0, 3):
        world = smpl_poses()
        people[person] = {"pose": smpl_poses(UPSIDE_DOWN), "trans": np.tile([0, 0.2, 4.0],
                                                                             (FRAMES, 1)),
                          "pose_world": world, "trans_world": np.cumsum(np.full((FRAMES, 3),
                                                                                0.05), axis=0),
                          "betas": np.zeros((FRAMES, 10)), "verts": np.zeros((FRAMES, 8, 3)),
                          "frame_ids": np.arange(FRAMES)}
    path = folder / "output.pkl"
    joblib.dump(people, path)
    return path, {}


def vibe(folder):
    people = {1: {"pose": smpl_poses(UPSIDE_DOWN), "betas": np.zeros((FRAMES, 10)),
                  "pred_cam": np.ones((FRAMES, 3)), "orig_cam": np.ones((FRAMES, 4)),
                  "verts": np.zeros((FRAMES, 8, 3)), "joints3d": np.zeros((FRAMES, 49, 3)),
                  "frame_ids": np.arange(FRAMES)}}
    path = folder / "vibe_output.pkl"
    joblib.dump(people, path)
    return path, {}


def phalp(folder):
    mats = rotmats(smpl_poses(UPSIDE_DOWN))
    frames = {}
    for t in range(FRAMES):
        ids = [1, 2] if t < 4 else [1]
        frames[f"{t + 1:06d}.jpg"] = {
            "time": t, "shot": 0, "tracked_ids": ids, "tracked_bbox": [np.zeros(4)] * len(ids),
            "smpl": [{"global_orient": mats[t, :1], "body_pose": mats[t, 1:],
                      "betas": np.zeros(10)} for _ in ids],
            "camera": [np.array([0.1 * i, 0.3, 8.0]) for i in ids],
            "3d_joints": [np.zeros((45, 3))] * len(ids)}
    path = folder / "demo_video.pkl"
    joblib.dump(frames, path)
    return path, {}


def tram(folder):
    import torch

    poses = smpl_poses(UPSIDE_DOWN)
    path = folder / "hps_track_0.npy"
    np.save(path, {"pred_rotmat": torch.tensor(rotmats(poses), dtype=torch.float32),
                   "pred_trans": torch.zeros((FRAMES, 1, 3)),
                   "pred_shape": torch.zeros((FRAMES, 10)), "frame": torch.arange(FRAMES)},
            allow_pickle=True)
    return path, {}


def aistpp(folder):
    path = folder / "gBR_sBM_cAll_d04_mBR0_ch01.pkl"
    scaling = 93.0
    trans = np.tile([10.0, 0.0, 20.0], (FRAMES, 1))  # centimetres: 0.1 m and 0.2 m
    with open(path, "wb") as handle:
        pickle.dump({"smpl_loss": 0.1, "smpl_poses": smpl_poses(),
                     "smpl_scaling": np.array([scaling]), "smpl_trans": trans}, handle)
    return path, {}


def phc(folder):
    import torch

    clips = {f"0-ACCAD_walk{i}_poses": {
        "pose_aa": torch.tensor(smpl_poses(Z_UP)), "trans": np.tile([0, -0.95, 0.95], (FRAMES, 1)),
        "root_trans_offset": torch.zeros((FRAMES, 3)), "beta": np.zeros(16),
        "gender": "neutral", "fps": 30, "pose_quat_global": np.zeros((FRAMES, 24, 4))}
        for i in range(2)}
    path = folder / "amass_isaac_walk.pkl"
    joblib.dump(clips, path)
    return path, {}


AMP_NAMES = ["pelvis", "torso", "head", "right_upper_arm", "right_lower_arm", "right_hand",
             "left_upper_arm", "left_lower_arm", "left_hand", "right_thigh", "right_shin",
             "right_foot", "left_thigh", "left_shin", "left_foot"]
AMP_PARENTS = [-1, 0, 1, 1, 3, 4, 1, 6, 7, 0, 9, 10, 0, 12, 13]
AMP_OFFSETS = [(0, 0, 0), (0, 0, 0.24), (0, 0, 0.22), (0, -0.18, 0.2), (0, 0, -0.27),
               (0, 0, -0.23), (0, 0.18, 0.2), (0, 0, -0.27), (0, 0, -0.23), (0, -0.08, 0),
               (0, 0, -0.42), (0, 0, -0.41), (0, 0.08, 0), (0, 0, -0.42), (0, 0, -0.41)]


def tensor_dict(values, dtype="float32"):
    return {"arr": np.asarray(values, dtype), "context": {"dtype": dtype}}


def amp_poselib(folder):
    rotation = np.zeros((FRAMES, 15, 4))
    rotation[..., 3] = 1.0
    root = np.zeros((FRAMES, 3))
    root[:, 0] = np.linspace(0, 0.5, FRAMES)
    root[:, 2] = 0.89
    motion = OrderedDict([
        ("rotation", tensor_dict(rotation)), ("root_translation", tensor_dict(root)),
        ("global_velocity", tensor_dict(np.zeros((FRAMES, 15, 3)))),
        ("global_angular_velocity", tensor_dict(np.zeros((FRAMES, 15, 3)))),
        ("skeleton_tree", OrderedDict([("node_names", AMP_NAMES),
                                       ("parent_indices", tensor_dict(AMP_PARENTS, "int64")),
                                       ("local_translation", tensor_dict(AMP_OFFSETS))])),
        ("is_local", True), ("fps", 60), ("__name__", "SkeletonMotion")])
    path = folder / "amp_humanoid_run.npy"
    np.save(path, motion, allow_pickle=True)
    return path, {}


def bvh(folder):
    return write_bvh(folder / "walk.bvh", "mixamo"), {}


def joints(folder):
    path = folder / "a_person_is_boxing.npy"
    np.save(path, walking(FRAMES)[None])  # T2M-GPT's (1, T, 22, 3)
    return path, {}


def mdm(folder):
    path = folder / "results.npy"
    write_results(path, count=2, frames=FRAMES)
    return path, {}


def humanml3d(folder):
    root = folder / "HumanML3D"
    (root / "new_joints").mkdir(parents=True)
    (root / "texts").mkdir()
    np.save(root / "new_joints" / "000001.npy", walking(FRAMES))
    (root / "texts" / "000001.txt").write_text("a person walks forward#a/DET#0.0#0.0\n")
    return root, {}


def humanml3d_vec(folder):
    path = folder / "000001.npy"
    np.save(path, encode(walking(FRAMES).astype(np.float64))[0].astype(np.float32))
    return path, {}


def amass(folder):
    path = folder / "walk_poses.npz"  # z up: the root turned onto it, the pelvis 0.95 m up
    np.savez(path, poses=smpl_poses(Z_UP), trans=np.tile([0, -0.95, 0.95], (FRAMES, 1)),
             betas=np.zeros(10), gender="neutral", mocap_framerate=60.0)
    return path, {}


def motioncritic(folder):
    path = folder / "pair.npz"
    np.savez(path, {"prompt": list("ABCD"), "motion": [rot6d_motion()[None]] * 4})
    return path, {}


def actor(folder):
    from tests.motion.body_model_files import model_arrays

    rest = model_arrays(24)["v_template"] * [1, -1, -1]  # the synthetic body, y down as ACTOR's
    path = folder / "generation.npy"
    frames = np.stack([rest + [0, 0, 0.05 * t] for t in range(3)], axis=-1)  # (V, 3, T)
    np.save(path, np.stack([np.stack([frames] * 2)]).astype(np.float32))  # (1, 2, V, 3, T)
    return path, {}


def npz(folder):
    from motion.formats import npz as interchange
    from motion.motion import Motion

    path = folder / "motions.npz"
    interchange.save(path, [Motion(walking(FRAMES), "smpl22", 20.0, "walk", "real")])
    return path, {}


def smplx_poses(frames=FRAMES, root=np.zeros(3)):
    """Return SMPL-X poses (T, 165): the root turned, a knee bending, fingers curling."""
    poses = np.zeros((frames, 165))
    poses[:, :3] = root
    poses[:, 3 * 4] = np.linspace(0, 0.6, frames)
    poses[:, 77:165:3] = np.linspace(0, 0.5, frames)[:, None]  # every finger joint about z
    return poses


def smplx(folder):
    path = folder / "2_scott_0_1_1.npz"  # BEAT2's smplxflame_30 layout
    np.savez(path, poses=smplx_poses(), trans=np.tile([0, 0.0, 0.1], (FRAMES, 1)),
             betas=np.zeros(300), expressions=np.zeros((FRAMES, 100)), model="smplx2020",
             gender="neutral", mocap_frame_rate=30)
    return path, {}


def a2m(folder):
    joints = np.stack([walking(FRAMES, 24, seed=i) for i in range(3)])  # humanact12, y up
    np.save(folder / "motions.npy", joints.reshape(3, FRAMES, 72))
    np.save(folder / "classes.npy", np.array([0, 3, 5]))
    return folder / "motions.npy", {"classes_path": folder / "classes.npy"}


EXAMPLES = {name: function for name, function in globals().items()
            if name in ("wham", "vibe", "phalp", "tram", "aistpp", "phc", "amp_poselib", "bvh",
                        "joints", "mdm", "humanml3d", "humanml3d_vec", "amass", "motioncritic",
                        "actor", "npz", "a2m", "smplx")}


def _pickled(name, value):
    def write(folder):
        path = folder / name
        joblib.dump(value, path)
        return path
    return write


def _saved(name, value):
    def write(folder):
        path = folder / name
        np.save(path, value, allow_pickle=True)
        return path
    return write


def _bvh_broken(folder):
    path = write_bvh(folder / "walk.bvh", "bandai")
    path.write_text(path.read_text().replace("Frames: 4", "Frames: 5"))
    return path


def _humanml3d_broken(folder):
    root = folder / "HumanML3D"
    (root / "new_joints").mkdir(parents=True)
    np.save(root / "new_joints" / "000001.npy", np.zeros((FRAMES, 22, 2)))
    return root


MALFORMED = {
    "wham": (_pickled("output.pkl", {0: {"pose": np.zeros((FRAMES, 69)),
                                         "trans": np.zeros((FRAMES, 3)),
                                         "pose_world": np.zeros((FRAMES, 69)),
                                         "trans_world": np.zeros((FRAMES, 3))}}),
             r"\[0\]\.pose_world has shape \(6, 69\); expected \(T, 72\)"),
    "vibe": (_pickled("vibe_output.pkl", {1: {"pose": np.zeros((FRAMES, 3)),
                                              "pred_cam": np.zeros((FRAMES, 3))}}),
             r"\[1\]\.pose has shape \(6, 3\)"),
    "phalp": (_pickled("demo.pkl", {"000001.jpg": {"time": 0, "tracked_ids": [1, 2],
                                                   "smpl": [{}]}}),
              "lists 2 tracked_ids but 1 smpl entries"),
    "tram": (_saved("hps_track_0.npy", {"pred_rotmat": np.zeros((FRAMES, 24, 3)),
                                        "pred_trans": np.zeros((FRAMES, 3))}),
             r"pred_rotmat has shape \(6, 24, 3\)"),
    "aistpp": (_pickled("gBR_x.pkl", {"smpl_poses": np.zeros((FRAMES, 72)),
                                      "smpl_trans": np.zeros((FRAMES + 1, 3)),
                                      "smpl_scaling": np.array([1.0])}),
               r"smpl_trans has shape \(7, 3\); expected \(6, 3\)"),
    "phc": (_pickled("lib.pkl", {"clip": {"pose_aa": np.zeros((FRAMES, 70)),
                                          "trans": np.zeros((FRAMES, 3))}}),
            r"pose_aa has shape \(6, 70\)"),
    "amp_poselib": (_saved("run.npy", OrderedDict([
        ("rotation", tensor_dict(np.zeros((FRAMES, 15, 4)))),
        ("root_translation", tensor_dict(np.zeros((FRAMES, 3)))),
        ("skeleton_tree", OrderedDict([("node_names", AMP_NAMES),
                                       ("parent_indices", tensor_dict(AMP_PARENTS, "int64")),
                                       ("local_translation", tensor_dict(AMP_OFFSETS))]))])),
        "zero quaternions"),
    "bvh": (_bvh_broken, r"expected Frames \(5\)"),
    "joints": (_saved("a.npy", np.full((FRAMES, 22, 3), np.nan)), "NaN or infinite"),
    "mdm": (_saved("results.npy", {"motion": np.zeros((2, 22, 3, FRAMES)), "text": ["a"]}),
            "text"),
    "humanml3d": (_humanml3d_broken, r"\(6, 22, 2\)"),
    "humanml3d_vec": (_saved("000001.npy", np.full((FRAMES, 263), np.inf)), "NaN or infinite"),
    "amass": (lambda folder: _npz(folder / "a.npz", poses=np.zeros((FRAMES, 99)),
                                  trans=np.zeros((FRAMES, 3)), mocap_framerate=60.0),
              r"poses has shape \(6, 99\)"),
    "motioncritic": (lambda folder: _npz(folder / "pair.npz", {"prompt": list("AB"),
                                                               "motion": [np.zeros((1, 24, 6, 60))] * 2}),
                     r"has shape \(24, 6, 60\)"),
    "actor": (_saved("generation.npy", np.zeros((1, 2, 6890, 3, 0))), r"\(1, 2, 6890, 3, 0\)"),
    "npz": (lambda folder: _npz(folder / "motions.npz", joints=np.zeros((1, FRAMES, 22, 3)),
                                actions=np.array(["a", "b"]), skeleton="smpl22", fps=20.0,
                                source="real"), "actions"),
    "a2m": (lambda folder: (_npy_pair(folder)), "class"),
    "smplx": (lambda folder: _npz(folder / "beat.npz", poses=np.zeros((FRAMES, 165)),
                                  trans=np.zeros((FRAMES, 2)), mocap_frame_rate=30),
              r"trans has shape \(6, 2\); expected \(6, 3\)"),
}


def _npz(path, *args, **arrays):
    np.savez(path, *args, **arrays)
    return path


def _npy_pair(folder):
    np.save(folder / "motions.npy", np.zeros((3, FRAMES, 72)))
    np.save(folder / "classes.npy", np.arange(5))
    return folder / "motions.npy"


MALFORMED_OPTIONS = {"a2m": lambda folder: {"classes_path": folder / "classes.npy"}}


def _own_examples():
    """Add the examples that a format brings in its own file, ``examples/<format>.py``
    beside this one: ``example(folder) -> (path, options)``, ``malformed(folder) -> path``,
    ``MALFORMED_MESSAGE`` (a regular expression of its error) and optionally
    ``malformed_options(folder) -> options``. A new format is its module and that file."""
    folder = Path(__file__).parent / "examples"
    for path in sorted(folder.glob("[!_]*.py")):
        module = importlib.import_module(f"tests.motion.examples.{path.stem}")
        EXAMPLES[path.stem] = module.example
        MALFORMED[path.stem] = (module.malformed, module.MALFORMED_MESSAGE)
        if hasattr(module, "malformed_options"):
            MALFORMED_OPTIONS[path.stem] = module.malformed_options


_own_examples()
