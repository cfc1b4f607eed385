"""Files as collaborators send them, good and tampered, for the tests of safe loading.

A tampered file holds :class:`RunsCommand`, whose pickle makes the reader call
``os.system("touch MARKER")``: Python's unpickler (``np.load(..., allow_pickle=True)``,
``pickle.load``, ``joblib.load``, smplx's model loading) runs it; the marker's absence
proves nothing ran. :func:`python2_pickle` writes pickles as Python 2's cPickle did
(protocol 2, ``str`` as byte strings), the way the official SMPL ``.pkl`` files were
written, with chumpy arrays and scipy sparse matrices by name.
"""

from __future__ import annotations

import io
import os
import pickle
import struct
from pathlib import Path

import numpy as np

from tests.motion.body_model_files import model_arrays

SYSTEM = f"{os.system.__module__}.{os.system.__qualname__}"  # "posix.system" on Linux


class RunsCommand:
    """Unpickled by Python's unpickler, this runs ``touch marker``."""

    def __init__(self, marker: Path):
        self.marker = Path(marker)

    def __reduce__(self):
        return os.system, (f"touch '{self.marker}'",)


# --- tampered files of every format that reads pickles ----------------------------------------


def mdm_results(path: Path, marker: Path) -> Path:
    """An MDM ``results.npy`` whose dict holds the payload beside a real motion."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, {"motion": np.zeros((1, 22, 3, 8), np.float32), "text": ["a walk"],
                   "lengths": np.array([8]), "hook": RunsCommand(marker)}, allow_pickle=True)
    return path


def mdm_params(path: Path, marker: Path) -> Path:
    """An MDM ``sample00_rep00_smpl_params.npy`` with the payload as its text."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, {"vertices": np.zeros((6890, 3, 4)), "faces": np.zeros((10, 3), np.int64),
                   "text": RunsCommand(marker), "length": 4}, allow_pickle=True)
    return path


def amass_npz(path: Path, marker: Path) -> Path:
    """An AMASS ``.npz`` whose gender is an object array holding the payload."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, poses=np.zeros((4, 156)), trans=np.zeros((4, 3)), betas=np.zeros(16),
             gender=np.array(RunsCommand(marker), dtype=object), mocap_framerate=np.array(60.0))
    return path


def motioncritic_npz(path: Path, marker: Path) -> Path:
    """A MotionCritic ``.npz`` whose ``arr_0`` dict holds the payload."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, np.array({"prompt": ["a", "b", "c", "d"], "motion": RunsCommand(marker)},
                            dtype=object))
    return path


def smpl_pkl(root: Path, marker: Path, gender: str = "NEUTRAL") -> Path:
    """``root/smpl/SMPL_<GENDER>.pkl``: a real model's arrays and the payload."""
    path = root / "smpl" / f"SMPL_{gender}.pkl"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps({**model_arrays(24), "hook": RunsCommand(marker)}, protocol=2))
    return path


def smplh_npz(root: Path, marker: Path, gender: str = "male") -> Path:
    """``root/smplh/<gender>/model.npz`` (AMASS's layout) with the payload as a member."""
    path = root / "smplh" / gender / "model.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = model_arrays(52)
    arrays.update(hands_componentsl=np.eye(45), hands_componentsr=np.eye(45),
                  hands_meanl=np.zeros(45), hands_meanr=np.zeros(45),
                  bs_style=np.array(RunsCommand(marker), dtype=object))
    np.savez(path, **arrays)
    return path


def plain_pickle(path: Path, marker: Path, protocol: int = pickle.DEFAULT_PROTOCOL) -> Path:
    """A pickle of data with the payload in a list."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps({"root": np.zeros(3), "hook": [RunsCommand(marker)]},
                                  protocol=protocol))
    return path


def joblib_file(path: Path, marker: Path, compress=0) -> Path:
    """A joblib motion library: arrays (written after their wrappers) and the payload."""
    import joblib

    path.parent.mkdir(parents=True, exist_ok=True)
    joblib.dump({"pose": np.zeros((4, 24, 3)), "hook": RunsCommand(marker)}, path,
                compress=compress)
    return path


def joblib_object_array(path: Path, marker: Path) -> Path:
    """joblib writes an array of objects as a pickle of its own: the payload is in there."""
    import joblib

    path.parent.mkdir(parents=True, exist_ok=True)
    joblib.dump({"names": np.array(["a", RunsCommand(marker)], dtype=object)}, path)
    return path


def torch_storage(path: Path, marker: Path) -> Path:
    """A pickled tensor whose storage bytes (torch's legacy serialisation) hold the payload:
    torch's ``_load_from_bytes`` unpickles them with ``weights_only`` off."""
    import torch

    inner = io.BytesIO()
    info = {"protocol_version": 1001, "little_endian": True,
            "type_sizes": {"short": 2, "int": 4, "long": 4}}
    for part in (0x1950A86A20F9469CFC6C, 1001, info, RunsCommand(marker), []):
        pickle.dump(part, inner, protocol=2)

    class Storage:
        def __reduce__(self):
            return torch.storage._load_from_bytes, (inner.getvalue(),)

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps({"pose": Storage()}, protocol=4))
    return path


# --- Python 2 pickles: the official SMPL files ---------------------------------------------------


class Py2Object:
    """An instance of ``module.name`` pickled by state, as protocol 2 writes new-style objects."""

    def __init__(self, module: str, name: str, state: dict):
        self.module, self.name, self.state = module, name, state


def python2_pickle(value) -> bytes:
    """Return ``value`` pickled as Python 2's cPickle (protocol 2) wrote it: ``str`` as byte
    strings, numpy arrays by ``numpy.core.multiarray._reconstruct``, sets and objects by
    name. Handles None, bools, ints, floats, str, tuples, lists, dicts, sets, numpy arrays
    and :class:`Py2Object`."""
    out = [b"\x80\x02"]

    def text(s):
        raw = s if isinstance(s, bytes) else s.encode("latin1")
        out.append(b"U" + bytes([len(raw)]) + raw if len(raw) < 256
                   else b"T" + struct.pack("<i", len(raw)) + raw)

    def name(module, qualname):
        out.append(b"c" + module.encode() + b"\n" + qualname.encode() + b"\n")

    def items(values, end):
        out.append(b"(")
        for v in values:
            save(v)
        out.append(end)

    def save(v):
        if v is None:
            out.append(b"N")
        elif v is True or v is False:
            out.append(b"\x88" if v else b"\x89")
        elif isinstance(v, int):
            out.append(b"J" + struct.pack("<i", v))
        elif isinstance(v, float):
            out.append(b"G" + struct.pack(">d", v))
        elif isinstance(v, (str, bytes)):
            text(v)
        elif isinstance(v, tuple):
            items(v, b"t")
        elif isinstance(v, list):
            out.append(b"]")
            if v:
                items(v, b"e")
        elif isinstance(v, dict):
            out.append(b"}")
            if v:
                items([x for pair in v.items() for x in pair], b"u")
        elif isinstance(v, set):
            name("__builtin__", "set")
            save((sorted(v),))
            out.append(b"R")
        elif isinstance(v, np.ndarray):
            array = np.ascontiguousarray(v)
            name("numpy.core.multiarray", "_reconstruct")
            name("numpy", "ndarray")
            save((0,))
            text("b")
            out.append(b"\x87R")  # TUPLE3, REDUCE: an empty array
            out.append(b"(")  # its state: version, shape, dtype, Fortran order, bytes
            save(1)
            save(tuple(array.shape))
            name("numpy", "dtype")
            save((array.dtype.str[1:], False, True))
            out.append(b"R")
            save((3, "|" if array.dtype.itemsize == 1 else "<", None, None, None, -1, -1, 0))
            out.append(b"b")
            save(False)
            text(array.tobytes())
            out.append(b"tb")
        elif isinstance(v, Py2Object):
            name(v.module, v.name)
            out.append(b")\x81")  # EMPTY_TUPLE, NEWOBJ
            save(v.state)
            out.append(b"b")
        else:
            raise TypeError(f"python2_pickle cannot write {type(v).__name__}")

    save(value)
    out.append(b".")
    return b"".join(out)


def official_smpl(root: Path, gender: str = "NEUTRAL") -> Path:
    """Write ``root/smpl/SMPL_<GENDER>.pkl`` as the official SMPL files are: a Python 2
    pickle whose ``shapedirs`` is a chumpy ``Ch`` and whose ``J_regressor`` (and its
    prior) are scipy csc matrices, beside plain arrays and the training notes."""
    arrays = model_arrays(24)
    regressor = arrays["J_regressor"]
    rows, cols = np.nonzero(regressor.T)  # column-major: csc's order
    indptr = np.searchsorted(rows, np.arange(regressor.shape[1] + 1)).astype(np.int32)
    csc = {"_shape": regressor.shape, "maxprint": 50, "format": "csc",
           "indices": cols.astype(np.int32), "indptr": indptr,
           "data": regressor.T[rows, cols].astype(np.float64)}
    model = {
        "J_regressor": Py2Object("scipy.sparse.csc", "csc_matrix", csc),
        "J_regressor_prior": Py2Object("scipy.sparse.csc", "csc_matrix", dict(csc)),
        "shapedirs": Py2Object("chumpy.ch", "Ch", {
            "x": arrays["shapedirs"], "_dirty_vars": {"x"}, "_itr": None,
            "_depends_on_deps": {}, "_make_dense": False, "_make_sparse": False}),
        "v_template": arrays["v_template"], "posedirs": arrays["posedirs"],
        "weights": arrays["weights"], "weights_prior": arrays["weights"],
        "kintree_table": arrays["kintree_table"].astype(np.int64), "f": arrays["f"],
        "J": arrays["v_template"][:24], "vert_sym_idxs": np.arange(6890, dtype=np.int64),
        "bs_style": "lbs", "bs_type": "lrotmin",
        "pose_training_info": {"nSubjects_male": 0, "nSubjects_female": 0, "regressor": "x"},
    }
    path = root / "smpl" / f"SMPL_{gender}.pkl"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(python2_pickle(model))
    return path
