"""Small synthetic SMPL / SMPL+H model files in the real files' layout, for tests.

The real models are licensed and never shipped; these have the same keys and shapes
(6890 vertices, 24 or 52 joints) so the loading code runs for real through smplx. Each
joint owns a cluster of vertices centred exactly on its rest position, skinned to it
alone, so the joint regressor gives the joints back and posing is easy to predict.
"""

import pickle

import numpy as np

from motion.skeletons import SMPL_JOINTS, SMPL_PARENTS

VERTICES = 6890
# Rest positions (x = the body's left, y up, z forward), metres.
_PLACES = {
    "pelvis": (0, .95, 0), "spine1": (0, 1.05, 0), "spine2": (0, 1.18, 0),
    "spine3": (0, 1.3, 0), "neck": (0, 1.48, .01), "head": (0, 1.6, .03),
    "hip": (.1, .92, 0), "knee": (.11, .5, .02), "ankle": (.11, .08, -.02), "foot": (.12, .02, .12),
    "collar": (.06, 1.42, 0), "shoulder": (.18, 1.42, 0), "elbow": (.2, 1.15, -.02),
    "wrist": (.21, .9, .02), "hand": (.21, .82, .03),
}
SMPLH_PARENTS = tuple(SMPL_PARENTS[:22]) + tuple(
    parent for wrist in (20, 21) for finger in range(5)
    for parent in (wrist, 22 + (wrist - 20) * 15 + finger * 3, 23 + (wrist - 20) * 15 + finger * 3))


def rest_joints(count: int) -> np.ndarray:
    """Return the rest joints ``(count, 3)``: SMPL's 24, or SMPL+H's 22 plus 30 fingers."""
    joints = []
    for name in SMPL_JOINTS[: 24 if count == 24 else 22]:
        side, _, part = name.partition("_")
        x, y, z = _PLACES[part] if side in ("left", "right") else _PLACES[name]
        joints.append((-x if side == "right" else x, y, z))
    for index in range(len(joints), count):  # fingers: a few centimetres past each wrist
        wrist = joints[20 if index < 37 else 21]
        step = (index - 22) % 15
        joints.append((wrist[0] + np.sign(wrist[0]) * 0.02 * (1 + step % 3), wrist[1] - 0.06,
                       wrist[2] + 0.01 * (step // 3 - 2)))
    return np.array(joints, dtype=np.float64)


def model_arrays(count: int, seed: int = 0) -> dict:
    """Return the arrays of a model with ``count`` joints (24 SMPL, 52 SMPL+H)."""
    rng = np.random.default_rng(seed)
    joints = rest_joints(count)
    owner = np.arange(VERTICES) % count
    offsets = rng.normal(scale=0.03, size=(VERTICES, 3))
    for joint in range(count):  # centre each cluster exactly on its joint
        offsets[owner == joint] -= offsets[owner == joint].mean(axis=0)
    template = joints[owner] + offsets
    regressor = np.zeros((count, VERTICES))
    for joint in range(count):
        regressor[joint, owner == joint] = 1.0 / np.sum(owner == joint)
    weights = np.zeros((VERTICES, count))
    weights[np.arange(VERTICES), owner] = 1.0
    parents = SMPL_PARENTS if count == 24 else SMPLH_PARENTS
    faces = np.array([[i, i + count, i + 2 * count] for i in range(VERTICES - 2 * count)])
    return {
        "v_template": template,
        "shapedirs": np.zeros((VERTICES, 3, 10)),
        "posedirs": np.zeros((VERTICES, 3, (count - 1) * 9), np.float32),
        "J_regressor": regressor,
        "kintree_table": np.array([[4294967295] + list(parents[1:]), list(range(count))]),
        "weights": weights,
        "f": faces.astype(np.uint32),
    }


def write_smpl(root, gender="NEUTRAL"):
    """Write ``root/smpl/SMPL_<GENDER>.pkl`` and return its path."""
    path = root / "smpl" / f"SMPL_{gender}.pkl"
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as handle:
        pickle.dump(model_arrays(24), handle)
    return path


def write_smplh(root, gender="male"):
    """Write ``root/smplh/<gender>/model.npz`` (AMASS's layout) and return its path."""
    arrays = model_arrays(52)
    arrays.update(hands_componentsl=np.eye(45), hands_componentsr=np.eye(45),
                  hands_meanl=np.zeros(45), hands_meanr=np.zeros(45))
    path = root / "smplh" / gender / "model.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)
    return path


SMPLX_VERTICES = 10475
SMPLX_PARENTS = tuple(SMPL_PARENTS[:22]) + (15, 15, 15) + tuple(
    parent for wrist in (20, 21) for finger in range(5)
    for parent in (wrist, 25 + (wrist - 20) * 15 + finger * 3, 26 + (wrist - 20) * 15 + finger * 3))


def smplx_rest_joints() -> np.ndarray:
    """Return the SMPL-X rest joints (55, 3): the body's 22, jaw and eyes, 30 fingers."""
    body = rest_joints(52)
    face = [body[15] + (0, 0.02, 0.08), body[15] + (0.03, 0.06, 0.09), body[15] + (-0.03, 0.06, 0.09)]
    return np.concatenate([body[:22], face, body[22:]])


def write_smplx(root, gender="NEUTRAL"):
    """Write ``root/smplx/SMPLX_<GENDER>.npz`` (10 shape and 10 expression directions, as
    smplx's small models) and return its path."""
    count = 55
    rng = np.random.default_rng(1)
    joints = smplx_rest_joints()
    owner = np.arange(SMPLX_VERTICES) % count
    offsets = rng.normal(scale=0.03, size=(SMPLX_VERTICES, 3))
    for joint in range(count):
        offsets[owner == joint] -= offsets[owner == joint].mean(axis=0)
    regressor = np.zeros((count, SMPLX_VERTICES))
    for joint in range(count):
        regressor[joint, owner == joint] = 1.0 / np.sum(owner == joint)
    weights = np.zeros((SMPLX_VERTICES, count))
    weights[np.arange(SMPLX_VERTICES), owner] = 1.0
    faces = np.array([[i, i + count, i + 2 * count] for i in range(SMPLX_VERTICES - 2 * count)])
    path = root / "smplx" / f"SMPLX_{gender}.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path, v_template=joints[owner] + offsets,
        shapedirs=np.zeros((SMPLX_VERTICES, 3, 20), np.float32),
        posedirs=np.zeros((SMPLX_VERTICES, 3, (count - 1) * 9), np.float32),
        J_regressor=regressor, weights=weights, f=faces.astype(np.uint32),
        kintree_table=np.array([[4294967295] + list(SMPLX_PARENTS[1:]), list(range(count))]),
        hands_componentsl=np.eye(45), hands_componentsr=np.eye(45),
        hands_meanl=np.zeros(45), hands_meanr=np.zeros(45),
        lmk_faces_idx=np.arange(51), lmk_bary_coords=np.full((51, 3), 1 / 3),
        joint2num=np.array({"pelvis": 0}, dtype=object))
    return path
