"""Safe loading: data files read as Python's own readers read them, tampered ones refused.

Every tampered file is first shown to be a real attack: Python's unpickler (or
``np.load(allow_pickle=True)``, ``joblib.load``, smplx's model loading) runs its payload
and the marker file appears; :func:`load_data` on the same file raises an error naming
the file and the refused ``module.qualname``, and no marker appears.
"""

import collections
import pickle

import numpy as np
import pytest
import scipy.sparse
import torch

from motion.safe_load import (
    DataFileError,
    RefusedObject,
    load_data,
    load_npy,
    load_npz,
    npy_header,
    npz_names,
)
from tests.motion import untrusted_files as untrusted
from tests.motion.body_model_files import model_arrays, write_smpl

VALUES = {
    "array": np.arange(6, dtype=np.float32).reshape(2, 3),
    "fortran": np.asfortranarray(np.arange(6.0).reshape(2, 3)),
    "big_endian": np.arange(3, dtype=">i4"),
    "text": np.array(["ab", "c"]), "bytes_array": np.array([b"x"]),
    "objects": np.array([1, "a", None, [2.5]], dtype=object),
    "record": np.zeros(2, dtype=[("a", "<i4"), ("b", "<f8", (2,))]),
    "zero_d": np.array(3.0), "empty": np.zeros((0, 3)),
    "scalars": [np.float64(1.5), np.int64(-3), np.bool_(True), np.float32(2.0)],
    "dtype": np.dtype("f4"),
    "python": [None, True, 7, 2 ** 70, 1.5, 1 + 2j, "é", b"\x00\xff", bytearray(b"y"),
               (1, (2,)), {3, 4}, frozenset([5]), {"k": [1, {"deep": ()}]}],
    "ordered": collections.OrderedDict(b=1, a=2),
}


def same(a, b) -> bool:
    if isinstance(b, torch.Tensor):
        b = b.float().numpy() if b.dtype == torch.bfloat16 else b.detach().numpy()
    if scipy.sparse.issparse(b):
        return type(a) is type(b) and a.shape == b.shape and (a != b).nnz == 0
    if isinstance(b, np.ndarray):
        return (isinstance(a, np.ndarray) and a.shape == b.shape and a.dtype == b.dtype
                and (list(a.ravel()) == list(b.ravel()) if b.dtype.hasobject
                     else np.array_equal(a, b)))
    if isinstance(b, dict):
        return type(a) is type(b) and list(a) == list(b) and all(same(a[k], b[k]) for k in b)
    if isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(map(same, a, b))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("protocol", range(pickle.HIGHEST_PROTOCOL + 1))
def test_plain_data_reads_as_pythons_unpickler_reads_it_at_every_protocol(tmp_path, protocol):
    path = tmp_path / "data.pkl"
    path.write_bytes(pickle.dumps(VALUES, protocol=protocol))
    expected = pickle.loads(path.read_bytes())  # our own, trusted file
    assert same(load_data(path), expected)


def test_torch_tensors_and_sparse_matrices_become_arrays_without_torch(tmp_path):
    tensors = {"view": torch.arange(12.0).reshape(3, 4)[:, 1:3], "long": torch.tensor([1, -2]),
               "bfloat16": torch.tensor([1.5, -2.0], dtype=torch.bfloat16),
               "scalar": torch.tensor(3.0), "empty": torch.zeros(0, 3),
               "parameter": torch.nn.Parameter(torch.ones(2)), "bool": torch.tensor([True])}
    sparse = {"csc": scipy.sparse.csc_matrix(np.eye(3)), "csr": scipy.sparse.csr_matrix(np.eye(2)),
              "coo": scipy.sparse.coo_matrix(np.eye(2))}
    for protocol in (2, 4, 5):
        path = tmp_path / f"tensors{protocol}.pkl"
        path.write_bytes(pickle.dumps({**tensors, **sparse}, protocol=protocol))
        got = load_data(path)
        for key, tensor in tensors.items():
            assert isinstance(got[key], np.ndarray) and same(got[key], tensor), key
        for key, matrix in sparse.items():
            assert same(got[key], matrix), key


@pytest.mark.filterwarnings("ignore:the matrix subclass:PendingDeprecationWarning")
@pytest.mark.parametrize("compress", [0, 3, "gzip", "bz2", "xz", "lzma"])
def test_joblib_files_read_as_joblib_reads_them(tmp_path, compress):
    import joblib

    data = {**VALUES, "matrix": np.matrix([[1, 2]]), "tensor": torch.arange(4.0),
            "arrays": [np.ones((2, 2)), np.zeros(0)]}
    for protocol in (2, 4, 5):
        path = tmp_path / f"lib{protocol}.pkl"
        joblib.dump(data, path, compress=compress, protocol=protocol)
        expected = joblib.load(path)  # our own, trusted file
        got = load_data(path)
        expected["matrix"] = np.asarray(expected["matrix"])  # ours are plain arrays
        assert same(got, expected), (compress, protocol)


def test_npy_and_npz_of_objects_read_as_numpy_reads_them(tmp_path):
    results = {"motion": np.ones((2, 22, 3, 5), np.float32), "text": ["a", "b"],
               "lengths": np.array([5, 4]), "num_samples": 2}
    np.save(tmp_path / "results.npy", results)
    loaded = load_npy(tmp_path / "results.npy")
    assert loaded.shape == () and same(loaded.item(), results)
    assert npy_header(tmp_path / "results.npy") == ((), np.dtype(object))
    np.savez(tmp_path / "m.npz", poses=np.zeros((3, 72)), meta=np.array({"fps": 30}, dtype=object))
    arrays = load_npz(tmp_path / "m.npz")
    assert set(arrays) == set(npz_names(tmp_path / "m.npz")) == {"poses", "meta"}
    assert arrays["meta"].item() == {"fps": 30} and arrays["poses"].shape == (3, 72)
    assert set(load_npz(tmp_path / "m.npz", only=["poses"])) == {"poses"}
    poselib = collections.OrderedDict(rotation={"arr": np.zeros((4, 3, 4)), "context":
                                                {"dtype": "float32"}}, is_local=True)
    np.save(tmp_path / "amp_motion.npy", poselib)  # IsaacGym AMP's poselib layout
    assert same(load_data(tmp_path / "amp_motion.npy").item(), poselib)


def test_the_official_smpl_layout_reads_as_arrays_and_poses_like_the_plain_model(tmp_path):
    from motion.body_models import BodyModel

    path = untrusted.official_smpl(tmp_path / "official")
    data = load_data(path)
    arrays = model_arrays(24)
    assert isinstance(data["shapedirs"], np.ndarray)  # the chumpy Ch's array
    np.testing.assert_array_equal(data["shapedirs"], arrays["shapedirs"])
    assert isinstance(data["J_regressor"], scipy.sparse.csc_matrix)
    np.testing.assert_allclose(data["J_regressor"].toarray(), arrays["J_regressor"])
    assert data["bs_style"] == "lbs" and data["f"].dtype == np.uint32

    official = BodyModel("smpl", "neutral", path)
    plain = BodyModel("smpl", "neutral", write_smpl(tmp_path / "plain"))
    pose = np.random.default_rng(0).normal(scale=0.3, size=(3, 69))
    orient = np.zeros((3, 3))
    for a, b in zip(official.forward(orient, pose), plain.forward(orient, pose)):
        np.testing.assert_allclose(a, b, atol=1e-6)


# --- tampered files ----------------------------------------------------------------------------


def _unsafe_smplx(path):
    import smplx

    smplx.SMPL(str(path))


# Each: (write the tampered file, what reads it unsafely, as the code did before).
TAMPERED = {
    "npy": (lambda d, m: untrusted.mdm_results(d / "results.npy", m),
            lambda p: np.load(p, allow_pickle=True)),
    "npz member": (lambda d, m: untrusted.amass_npz(d / "take.npz", m),
                   lambda p: np.load(p, allow_pickle=True)["gender"]),
    "pickle protocol 0": (lambda d, m: untrusted.plain_pickle(d / "a.pkl", m, 0), pickle.loads),
    "pickle protocol 2": (lambda d, m: untrusted.plain_pickle(d / "a.pkl", m, 2), pickle.loads),
    "pickle protocol 5": (lambda d, m: untrusted.plain_pickle(d / "a.pkl", m, 5), pickle.loads),
    "joblib": (lambda d, m: untrusted.joblib_file(d / "lib.pkl", m), "joblib"),
    "joblib zlib": (lambda d, m: untrusted.joblib_file(d / "lib.pkl", m, 3), "joblib"),
    "joblib xz": (lambda d, m: untrusted.joblib_file(d / "lib.pkl", m, "xz"), "joblib"),
    "joblib array of objects": (lambda d, m: untrusted.joblib_object_array(d / "lib.pkl", m),
                                "joblib"),
    "torch storage bytes": (lambda d, m: untrusted.torch_storage(d / "t.pkl", m), pickle.loads),
    "SMPL model .pkl": (lambda d, m: untrusted.smpl_pkl(d, m), _unsafe_smplx),
    "SMPL+H model .npz": (lambda d, m: untrusted.smplh_npz(d, m),
                          lambda p: np.load(p, allow_pickle=True)["bs_style"]),
}


def _read_unsafely(reader, path):
    if reader == "joblib":
        import joblib

        return joblib.load(path)
    return reader(path.read_bytes() if reader is pickle.loads else path)


@pytest.mark.parametrize("kind", TAMPERED)
def test_a_tampered_file_runs_under_pythons_reader_but_is_refused_here(tmp_path, kind):
    write, unsafe = TAMPERED[kind]
    attack = write(tmp_path / "attack", tmp_path / "attack-ran")
    try:
        _read_unsafely(unsafe, attack)
    except Exception:
        pass  # the payload returns 0, not the object the reader expected
    assert (tmp_path / "attack-ran").exists()  # the file is a real attack

    marker = tmp_path / "ran"
    path = write(tmp_path / "ours", marker)
    with pytest.raises(RefusedObject) as refused:
        load_data(path)
    assert str(path) in str(refused.value) and untrusted.SYSTEM in str(refused.value)
    assert refused.value.name == untrusted.SYSTEM
    assert not marker.exists()


def _pickle_of(*ops: bytes) -> bytes:
    return b"\x80\x02" + b"".join(ops) + b"."


@pytest.mark.parametrize("data, words", [
    (_pickle_of(b"cbuiltins\neval\n", b"X\x04\x00\x00\x001+1;", b"\x85R"), ["builtins.eval"]),
    (_pickle_of(b"cnumpy.ma.core\n_mareconstruct\n"), ["numpy.ma.core._mareconstruct"]),
    (_pickle_of(b"cchumpy.ch_ops\nadd\n"), ["chumpy.ch_ops.add", "plain Ch arrays"]),
    (_pickle_of(b"cnumpy\ndtype\nX\x02\x00\x00\x00f8\x85R", b")R"), ["numpy", "plain data never"]),
    (_pickle_of(b"]", b"}b"), ["builtins.list", "plain data never"]),
    (_pickle_of(b"X\x01\x00\x00\x00xQ"), ["persistent id"]),
    (_pickle_of(b"cnumpy\nndarray\n"), ["holds numpy.ndarray", "not plain data"]),
    (_pickle_of(b"cbuiltins\nbytearray\nJ\x00\x00\x00\x7f\x85R"), ["builtins.bytearray"]),
    (b"ZF0x10\nsomething", ["joblib older than 0.10"]),
    (b"not a pickle at all", ["not a readable pickle"]),
])
def test_other_uses_of_pickle_are_refused_and_named(tmp_path, data, words):
    path = tmp_path / "odd.pkl"
    path.write_bytes(data)
    with pytest.raises(DataFileError) as error:
        load_data(path)
    for word in [str(path), *words]:
        assert word in str(error.value)


def test_damaged_arrays_say_what_is_wrong(tmp_path):
    import joblib

    joblib.dump({"pose": np.zeros((100, 3))}, tmp_path / "lib.pkl")
    raw = (tmp_path / "lib.pkl").read_bytes()
    (tmp_path / "cut.pkl").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(DataFileError, match=r"cut.pkl: joblib's array of shape \(100, 3\).*cut"):
        load_data(tmp_path / "cut.pkl")
    tensor = pickle.dumps(torch.arange(4.0), protocol=2)
    # stride 2 over 4 elements, 3 of them: element 4 does not exist
    beyond = tensor.replace(b"K\x04\x85", b"K\x03\x85").replace(b"K\x01\x85", b"K\x02\x85")
    (tmp_path / "beyond.pkl").write_bytes(beyond)
    with pytest.raises(DataFileError, match="beyond.pkl.*reaches element 4 of a storage of 4"):
        load_data(tmp_path / "beyond.pkl")
    (tmp_path / "bad.npy").write_bytes(b"\x93NUMPY\x01\x00garbage")
    with pytest.raises(DataFileError, match="bad.npy is not a readable .npy file"):
        load_data(tmp_path / "bad.npy")
    with pytest.raises(DataFileError, match="missing.pkl does not exist"):
        load_data(tmp_path / "missing.pkl")


def test_lists_that_hold_themselves_or_nest_deeply_are_still_data(tmp_path):
    loop = [1]
    loop.append(loop)
    (tmp_path / "loop.pkl").write_bytes(pickle.dumps({"loop": loop}))
    got = load_data(tmp_path / "loop.pkl")["loop"]
    assert got[0] == 1 and got[1] is got
    # Deeper than Python's recursion limit: read and checked without recursing.
    (tmp_path / "deep.pkl").write_bytes(_flat_list_pickle(5000))
    depth, value = 0, load_data(tmp_path / "deep.pkl")
    while value:
        value, depth = value[0], depth + 1
    assert depth == 5000


def _flat_list_pickle(depth: int) -> bytes:
    """A pickle of ``depth`` nested lists, written without recursion."""
    return b"\x80\x02]" + b"(]" * depth + b"e" * depth + b"."
