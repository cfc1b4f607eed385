"""SMPL, SMPL+H and SMPL-X body models the user supplies, through the ``smplx`` package.

The SMPL licence forbids shipping the model files, so formats that need one (``amass``,
``motioncritic``, ``actor``, and ``mdm`` meshes without their ``results.npy``) look for
them under a folder given as ``body_models`` or ``$STUDY_BODY_MODELS``, laid out as
``smplx.create`` expects::

    DIR/smpl/SMPL_NEUTRAL.pkl   (and SMPL_MALE.pkl, SMPL_FEMALE.pkl)
    DIR/smplh/SMPLH_MALE.npz    (or .pkl; or AMASS's layout DIR/smplh/male/model.npz)
    DIR/smplx/SMPLX_NEUTRAL.npz (and SMPLX_MALE.npz, SMPLX_FEMALE.npz)

The files are read as plain data (:mod:`motion.safe_load`: numpy arrays, and the
chumpy arrays and scipy sparse matrices of the official SMPL ``.pkl`` files, as arrays)
and handed to smplx parsed, so nothing in a tampered file runs (smplx's SMPL-X class
reads a file itself: it gets a copy holding only the numeric arrays). A missing file is a
:class:`BodyModelError` that names it, where to get it and where to put it.
Tensors stay inside this module: callers get numpy arrays.
"""

from __future__ import annotations

import contextlib
import io
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from motion import safe_load

ENV_VAR = "STUDY_BODY_MODELS"
GENDERS = ("neutral", "male", "female")
WHERE = {
    "smpl": "SMPL from https://smpl.is.tue.mpg.de (register, then 'SMPL for Python', "
            "version 1.1.0: basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl and the male and "
            "female files)",
    "smplh": "the extended SMPL+H model used by AMASS from https://mano.is.tue.mpg.de "
             "(register, then 'Extended SMPL+H model': smplh.tar.xz, whose male/model.npz, "
             "female/model.npz and neutral/model.npz go here as they are)",
    "smplx": "SMPL-X from https://smpl-x.is.tue.mpg.de (register, then 'Download SMPL-X "
             "v1.1 (NPZ+PKL)': models/smplx/SMPLX_NEUTRAL.npz, SMPLX_MALE.npz and "
             "SMPLX_FEMALE.npz; BEAT2's SMPLX_NEUTRAL_2020.npz is read too)",
}
# Names the files come with, accepted beside smplx's own (SMPL_NEUTRAL.pkl, ...).
ORIGINAL_NAMES = {
    ("smpl", "neutral"): ("basicmodel_neutral_lbs_10_207_0_v1.1.0.pkl",),
    ("smpl", "male"): ("basicmodel_m_lbs_10_207_0_v1.1.0.pkl",),
    ("smpl", "female"): ("basicmodel_f_lbs_10_207_0_v1.1.0.pkl",),
    ("smplx", "neutral"): ("SMPLX_NEUTRAL_2020.npz",),
}


class BodyModelError(ValueError):
    """A body model file is missing or unreadable; the message says how to supply it."""


def models_root(root: str | Path | None = None) -> Path | None:
    """Return the body models folder: ``root``, else ``$STUDY_BODY_MODELS``, else ``None``."""
    if root:
        return Path(root)
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR])
    return None


def candidates(kind: str, gender: str, root: Path) -> list[Path]:
    """Return where a model file may be, in the order they are tried."""
    upper = gender.upper()
    if kind == "smpl":
        names = [f"SMPL_{upper}.pkl", *ORIGINAL_NAMES.get((kind, gender), ())]
        return [root / "smpl" / name for name in names] + [root / name for name in names]
    if kind == "smplx":
        names = [f"SMPLX_{upper}.npz", *ORIGINAL_NAMES.get((kind, gender), ())]
        return [root / "smplx" / name for name in names] + [root / name for name in names]
    return [root / "smplh" / f"SMPLH_{upper}.npz", root / "smplh" / f"SMPLH_{upper}.pkl",
            root / "smplh" / gender / "model.npz", root / f"SMPLH_{upper}.npz"]


def find_body_model(kind: str, gender: str = "neutral", root: str | Path | None = None) -> Path:
    """Return the file of a body model, or raise :class:`BodyModelError` saying how to get it."""
    if kind not in WHERE:
        raise BodyModelError(f"unknown body model {kind!r}; known: {', '.join(WHERE)}")
    gender = str(gender).lower()
    if gender not in GENDERS:
        raise BodyModelError(f"gender {gender!r}; body models come as {', '.join(GENDERS)}")
    folder = models_root(root)
    expected = candidates(kind, gender, folder or Path("DIR"))[0]
    advice = (f"get {WHERE[kind]}; put it at {expected} (the layout smplx.create reads) "
              f"and pass --body-models DIR or set {ENV_VAR}=DIR")
    if folder is None:
        raise BodyModelError(f"this file needs the {kind.upper()} body model "
                             f"({expected.name}), which is licensed and not shipped; {advice}")
    for path in candidates(kind, gender, folder):
        if path.is_file():
            return path
    raise BodyModelError(f"no {kind.upper()} {gender} body model in {folder}: {expected} is "
                         f"missing; {advice}")


class BodyModel:
    """One SMPL or SMPL+H model: pose parameters to joints and vertices (numpy in and out)."""

    def __init__(self, kind: str, gender: str, path: Path):
        import smplx
        import torch
        from smplx.utils import Struct

        self.kind, self.gender, self.path = kind, gender, Path(path)
        options = {"gender": gender, "batch_size": 1}
        if kind == "smplh":
            options.update(use_pca=False, flat_hand_mean=True, ext=self.path.suffix[1:])
            build = smplx.SMPLH
        else:
            build = smplx.SMPL
        try:
            # The file is read as data here and handed over parsed: smplx's own reading
            # would unpickle it (and run whatever a tampered file asks for).
            data = safe_load.load_data(self.path)
        except safe_load.RefusedObject as exc:
            raise BodyModelError(str(exc)) from None
        except safe_load.DataFileError as exc:
            raise BodyModelError(f"{exc}; {WHERE[kind]}") from None
        try:
            if not isinstance(data, dict) or not all(isinstance(key, str) for key in data):
                raise TypeError(f"it holds {type(data).__name__}, not a dict of arrays by name")
            with contextlib.redirect_stdout(io.StringIO()):  # smplx prints shape warnings
                self._model = build(str(self.path), data_struct=Struct(**data), **options).eval()
        except Exception as exc:  # missing keys and wrong shapes of a damaged file
            raise BodyModelError(f"{self.path} is not a readable {kind.upper()} model file "
                                 f"({type(exc).__name__}: {exc}); {WHERE[kind]}") from exc
        self._torch = torch
        self.faces = np.asarray(self._model.faces, dtype=np.int64)
        self.n_betas = int(self._model.num_betas)
        self.n_body_joints = 24 if kind == "smpl" else 22
        self.regressor = self._model.J_regressor.numpy().astype(np.float64)

    def forward(self, global_orient, body_pose, transl=None, betas=None, hand_pose=None):
        """Return joints ``(T, J, 3)`` (the body's joints: 24 SMPL, 22 SMPL+H) and
        vertices ``(T, V, 3)`` of axis-angle poses ``global_orient`` ``(T, 3)`` and
        ``body_pose`` ``(T, 3 * (J - 1))``, translations ``(T, 3)``, shape ``betas``."""
        torch = self._torch
        frames = len(global_orient)

        def tensor(values, width):
            values = np.zeros((frames, width)) if values is None else np.asarray(values)
            return torch.as_tensor(values.reshape(frames, width), dtype=torch.float32)

        shape = np.zeros(self.n_betas) if betas is None else np.asarray(betas, float).ravel()
        shape = np.pad(shape[: self.n_betas], (0, max(0, self.n_betas - len(shape))))
        arguments = {
            "global_orient": tensor(global_orient, 3),
            "body_pose": tensor(body_pose, 3 * (self.n_body_joints - 1)),
            "transl": tensor(transl, 3),
            "betas": torch.as_tensor(np.tile(shape, (frames, 1)), dtype=torch.float32),
        }
        if self.kind == "smplh":
            hands = tensor(hand_pose, 90)
            arguments.update(left_hand_pose=hands[:, :45], right_hand_pose=hands[:, 45:])
        with torch.no_grad():
            output = self._model(**arguments)
        joints = output.joints[:, : self.n_body_joints].numpy().astype(np.float32)
        return joints, output.vertices.numpy().astype(np.float32)

    def regress(self, vertices: np.ndarray) -> np.ndarray:
        """Return the model's joints ``(T, 24 or 52, 3)`` of vertices ``(T, V, 3)``."""
        vertices = np.asarray(vertices, dtype=np.float64)
        if vertices.shape[1] != self.regressor.shape[1]:
            raise BodyModelError(f"vertices have {vertices.shape[1]} points; the "
                                 f"{self.kind.upper()} model at {self.path} has "
                                 f"{self.regressor.shape[1]}")
        return np.einsum("jv,tvc->tjc", self.regressor, vertices).astype(np.float32)


class SmplxModel:
    """One SMPL-X model: pose parameters to joints (body, and hands) and vertices."""

    HANDS = slice(25, 55)  # smplx's joint order: 22 body, jaw, eyes, 15 + 15 finger joints

    def __init__(self, gender: str, path: Path):
        import tempfile

        import smplx
        import torch

        self.kind, self.gender, self.path = "smplx", gender, Path(path)
        try:
            data = safe_load.load_data(self.path)
        except safe_load.RefusedObject as exc:
            raise BodyModelError(str(exc)) from None
        except safe_load.DataFileError as exc:
            raise BodyModelError(f"{exc}; {WHERE['smplx']}") from None
        if not isinstance(data, dict):
            raise BodyModelError(f"{self.path} holds {type(data).__name__}, not a SMPL-X "
                                 f"model; {WHERE['smplx']}")
        arrays = {key: value for key, value in data.items() if isinstance(value, np.ndarray)
                  and value.dtype != object}
        width = arrays.get("shapedirs", np.zeros((1, 3, 0))).shape[-1]
        self.n_betas = 300 if width >= 400 else 10
        self.n_expressions = 100 if width >= 400 else 10
        try:
            with tempfile.TemporaryDirectory() as folder, \
                    contextlib.redirect_stdout(io.StringIO()):
                clean = Path(folder) / f"SMPLX_{gender.upper()}.npz"
                np.savez(clean, **arrays)  # numbers only: smplx's np.load finds no pickle
                self._model = smplx.SMPLX(str(clean), gender=gender, use_pca=False,
                                          flat_hand_mean=True, num_betas=self.n_betas,
                                          num_expression_coeffs=self.n_expressions,
                                          ext="npz").eval()
        except Exception as exc:
            raise BodyModelError(f"{self.path} is not a readable SMPL-X model file "
                                 f"({type(exc).__name__}: {exc}); {WHERE['smplx']}") from exc
        self._torch = torch
        self.faces = np.asarray(self._model.faces, dtype=np.int64)

    def forward(self, poses, transl=None, betas=None, expression=None, hands: bool = False):
        """Return joints ``(T, 22 or 52, 3)`` (the body's, then 30 finger joints with
        ``hands``) and vertices of SMPL-X poses ``(T, 165)``: root 3, body 63, jaw 3,
        eyes 3 + 3, left hand 45, right hand 45 (axis-angle)."""
        torch = self._torch
        poses = np.asarray(poses, dtype=np.float64)
        frames = len(poses)

        def tensor(values, width):
            values = np.zeros((frames, width)) if values is None else np.asarray(values, float)
            values = values.reshape(frames, -1)[:, :width]
            values = np.pad(values, ((0, 0), (0, width - values.shape[1])))
            return torch.as_tensor(values, dtype=torch.float32)

        shape = np.zeros(self.n_betas) if betas is None else np.asarray(betas, float).ravel()
        shape = np.tile(shape, (frames, 1))
        arguments = {
            "global_orient": tensor(poses[:, :3], 3), "body_pose": tensor(poses[:, 3:66], 63),
            "jaw_pose": tensor(poses[:, 66:69], 3), "leye_pose": tensor(poses[:, 69:72], 3),
            "reye_pose": tensor(poses[:, 72:75], 3),
            "left_hand_pose": tensor(poses[:, 75:120], 45),
            "right_hand_pose": tensor(poses[:, 120:165], 45),
            "transl": tensor(transl, 3), "betas": tensor(shape, self.n_betas),
            "expression": tensor(expression, self.n_expressions),
        }
        with torch.no_grad():
            output = self._model(**arguments)
        joints = output.joints.numpy().astype(np.float32)
        joints = np.concatenate([joints[:, :22], joints[:, self.HANDS]], axis=1) if hands \
            else joints[:, :22]
        return joints, output.vertices.numpy().astype(np.float32)


@lru_cache(maxsize=8)
def _cached(kind: str, gender: str, path: str):
    if kind == "smplx":
        return SmplxModel(gender, Path(path))
    return BodyModel(kind, gender, Path(path))


def load_body_model(kind: str, gender: str = "neutral",
                    root: str | Path | None = None):
    """Return the body model of a kind and gender from the user's folder (cached)."""
    gender = str(gender).lower()
    path = find_body_model(kind, gender, root)
    return _cached(kind, gender, str(path.resolve()))


def rotation_6d_to_matrix(d6: np.ndarray) -> np.ndarray:
    """Return rotation matrices ``(..., 3, 3)`` of 6D rotations ``(..., 6)``.

    The 6D form is the matrix's first two rows (as MDM and ACTOR store it); the rows are
    rebuilt by Gram-Schmidt, the third as their cross product.
    """
    d6 = np.asarray(d6, dtype=np.float64)
    first = d6[..., :3] / np.linalg.norm(d6[..., :3], axis=-1, keepdims=True)
    second = d6[..., 3:] - np.sum(first * d6[..., 3:], axis=-1, keepdims=True) * first
    second = second / np.linalg.norm(second, axis=-1, keepdims=True)
    return np.stack([first, second, np.cross(first, second)], axis=-2)


def matrix_to_axis_angle(matrices: np.ndarray) -> np.ndarray:
    """Return axis-angle vectors ``(..., 3)`` of rotation matrices ``(..., 3, 3)``."""
    from scipy.spatial.transform import Rotation

    shape = matrices.shape[:-2]
    vectors = Rotation.from_matrix(np.asarray(matrices).reshape(-1, 3, 3)).as_rotvec()
    return vectors.reshape(shape + (3,))
