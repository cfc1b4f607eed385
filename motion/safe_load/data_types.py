"""The names a data pickle may use, each mapped to a builder written here.

numpy pickles an array as ``numpy.core.multiarray._reconstruct`` (numpy 2:
``numpy._core``) plus a ``BUILD`` of its shape, dtype and bytes, or (protocol 5) as
``_frombuffer``; a dtype as ``numpy.dtype``; a scalar as ``multiarray.scalar``. Python
pickles sets, bytes (protocols 0-2: ``_codecs.encode``) and OrderedDicts by name too.
Beyond these, three kinds of data that user files carry:

- chumpy's ``Ch`` (the official SMPL ``.pkl`` files): its state's ``x`` is the array;
- scipy's csc, csr and coo matrices (SMPL's joint regressor): rebuilt from their arrays
  and checked (``check_format(full_check=True)``);
- joblib's ``NumpyArrayWrapper``: the array's bytes follow the wrapper in the stream.

Python 2 names (``__builtin__``, ``copy_reg``) are listed beside Python 3's.
"""

from __future__ import annotations

import collections

import numpy as np

from motion.safe_load.unpickler import (
    DataFileError,
    Function,
    Kind,
    Marker,
    Placeholder,
)

NDARRAY = Marker("numpy.ndarray")
OBJECT = Marker("object")
MAX_DIMS = 64


def as_shape(value) -> tuple[int, ...]:
    """Return ``value`` as a shape (a tuple of non-negative ints), or raise ValueError."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        value = (value,)
    if (not isinstance(value, (tuple, list)) or len(value) > MAX_DIMS
            or not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 0
                       for n in value)):
        raise ValueError(f"{value!r} is not an array shape")
    return tuple(int(n) for n in value)


def _dtype_of(value) -> np.dtype:
    if not isinstance(value, np.dtype):
        raise TypeError(f"expected a numpy dtype, got {type(value).__name__}")
    return value


# --- numpy ---------------------------------------------------------------------------------


def _reconstruct(subtype, shape, typecode):
    # The array's shape, dtype and bytes come in its BUILD state (ndarray.__setstate__).
    if subtype is not NDARRAY:
        raise TypeError("only numpy.ndarray itself is rebuilt")
    return np.ndarray((0,), np.int8)


def _dtype(spec, align=False, copy=False):
    if not isinstance(spec, str):
        raise TypeError(f"a dtype is named by a string, not {type(spec).__name__}")
    return np.dtype(spec, bool(align), bool(copy))


def _scalar(dtype, data=None):
    dtype = _dtype_of(dtype)
    if dtype.hasobject:
        return data  # an object scalar pickles the object itself
    if isinstance(data, str):
        data = data.encode("latin1")  # Python 2 strings
    if not isinstance(data, bytes) or len(data) != dtype.itemsize:
        raise ValueError(f"a {dtype} scalar needs {dtype.itemsize} bytes")
    return np.frombuffer(data, dtype)[0]


def _frombuffer(buffer, dtype, shape, order="C"):
    dtype = _dtype_of(dtype)
    if not isinstance(buffer, (bytes, bytearray)) or dtype.hasobject:
        raise TypeError("an array is rebuilt from bytes of a dtype without objects")
    if order not in ("C", "F", "A", "K"):
        raise ValueError(f"order {order!r}")
    return np.frombuffer(buffer, dtype).reshape(as_shape(shape), order=order)


# --- Python's own --------------------------------------------------------------------------


def _sequence(value=()):
    if not isinstance(value, (list, tuple, set, frozenset)):
        raise TypeError(f"expected a list, got {type(value).__name__}")
    return value


def _encode(text, encoding="latin1"):
    if not isinstance(text, str) or encoding not in ("latin1", "latin-1"):
        raise TypeError("_codecs.encode only rebuilds bytes from latin-1 text")
    return text.encode("latin1")


def _bytes_of(value=b"", encoding=None):
    if isinstance(value, str) and encoding in ("latin1", "latin-1"):
        return value.encode("latin1")
    if isinstance(value, (bytes, bytearray)) and encoding is None:
        return bytes(value)
    raise TypeError("bytes are rebuilt from bytes or latin-1 text only")


def _complex(real=0.0, imag=0.0):
    if not all(isinstance(v, (int, float)) for v in (real, imag)):
        raise TypeError("complex takes two numbers")
    return complex(real, imag)


def _ordered_dict(items=()):
    return collections.OrderedDict(_sequence(items) if not isinstance(items, dict) else items)


def _dict(items=()):
    return dict(_sequence(items) if not isinstance(items, dict) else items)


def _reconstructor(kind, base, state):
    # copyreg._reconstructor: how protocols 0 and 1 make instances of plain classes.
    if not isinstance(kind, Kind) or base is not OBJECT or state is not None:
        raise TypeError("only known classes derived from object are rebuilt")
    return kind.make()


# --- chumpy, scipy.sparse, joblib -----------------------------------------------------------


class ChumpyArray(Placeholder):
    """chumpy's ``Ch``: the array in its state's ``x``."""

    name = "chumpy.ch.Ch"

    def finish(self, state, unpickler):
        x = state.get("x") if isinstance(state, dict) else None
        if not isinstance(x, (np.ndarray, int, float)) or np.asarray(x).dtype.hasobject:
            raise DataFileError(f"{unpickler.source}: a chumpy Ch without a numeric array "
                                f"in its state (got {type(x).__name__})")
        return np.asarray(x)


class SparseMatrix(Placeholder):
    """A scipy csc, csr or coo matrix, rebuilt from its arrays and checked."""

    def __init__(self, layout: str, cls_name: str):
        super().__init__()
        self.layout, self.name = layout, cls_name

    def finish(self, state, unpickler):
        import scipy.sparse

        if not isinstance(state, dict):
            raise DataFileError(f"{unpickler.source}: a {self.name} without its arrays")
        arrays = {k: state.get(k) for k in ("data", "indices", "indptr", "row", "col")}
        coords = state.get("coords")  # scipy >= 1.13 keeps a coo matrix's row and col here
        if isinstance(coords, tuple) and len(coords) == 2:
            arrays["row"], arrays["col"] = coords
        shape = state.get("_shape", state.get("shape"))
        try:
            shape = as_shape(shape)
            if len(shape) != 2 or any(a is not None and not isinstance(a, np.ndarray)
                                      for a in arrays.values()):
                raise ValueError("not a matrix of arrays")
            if self.layout == "coo":
                matrix = scipy.sparse.coo_matrix((arrays["data"], (arrays["row"], arrays["col"])),
                                                 shape=shape)
            else:
                build = scipy.sparse.csc_matrix if self.layout == "csc" else scipy.sparse.csr_matrix
                matrix = build((arrays["data"], arrays["indices"], arrays["indptr"]), shape=shape)
                matrix.check_format(full_check=True)
        except (TypeError, ValueError, IndexError) as exc:
            raise DataFileError(f"{unpickler.source}: a {self.name} whose arrays do not make a "
                                f"matrix ({exc})") from None
        return matrix


class JoblibArray(Placeholder):
    """joblib's ``NumpyArrayWrapper``: the array's bytes follow it in the stream.

    After the wrapper's state come (joblib >= 1.2) one byte giving the length of the
    alignment padding, the padding, then the array in ``order`` (an array of objects is
    a whole pickle of its own instead).
    """

    name = "joblib.numpy_pickle.NumpyArrayWrapper"
    CHUNK = 1 << 24

    def finish(self, state, unpickler):
        source = unpickler.source
        try:
            if not isinstance(state, dict) or state.get("subclass") not in (NDARRAY, MATRIX):
                raise ValueError("not an array wrapper")
            shape, order = as_shape(state.get("shape")), state.get("order", "C")
            dtype = _dtype_of(state.get("dtype"))
            if order not in ("C", "F"):
                raise ValueError(f"order {order!r}")
        except (TypeError, ValueError) as exc:
            raise DataFileError(f"{source}: a joblib array wrapper that is not one ({exc})") from None
        stream = unpickler.stream
        if dtype.hasobject:
            array = unpickler.nested().load()
            if not isinstance(array, np.ndarray) or array.shape != shape:
                raise DataFileError(f"{source}: joblib's array of objects of shape {shape} holds "
                                    f"{type(array).__name__}")
            return array
        if state.get("numpy_array_alignment_bytes") is not None:
            padding = stream.read(1)
            if padding:
                stream.read(padding[0])
        size = int(np.prod(shape, dtype=object)) * dtype.itemsize
        data = bytearray()
        while len(data) < size:
            chunk = stream.read(min(self.CHUNK, size - len(data)))
            if not chunk:
                raise DataFileError(f"{source}: joblib's array of shape {shape} ({dtype}) is cut "
                                    f"short: {len(data)} of {size} bytes")
            data += chunk
        array = np.frombuffer(data, dtype)
        array = (array.reshape(shape[::-1]).T if order == "F" else array.reshape(shape))
        if not array.dtype.isnative:  # as joblib does
            array = array.astype(array.dtype.newbyteorder("="))
        return array


def _old_joblib():
    raise DataFileError("the file was written by joblib older than 0.10 (its arrays are "
                        "separate files); read it with that joblib where you trust it and "
                        "save the arrays with numpy.savez")


MATRIX = Marker("numpy.matrix")


def _names() -> dict:
    names = {}
    for core in ("numpy.core", "numpy._core"):
        names[(f"{core}.multiarray", "_reconstruct")] = Function(f"{core}.multiarray._reconstruct",
                                                                 _reconstruct)
        names[(f"{core}.multiarray", "scalar")] = Function(f"{core}.multiarray.scalar", _scalar)
        names[(f"{core}.numeric", "_frombuffer")] = Function(f"{core}.numeric._frombuffer",
                                                             _frombuffer)
        names[(f"{core}.memmap", "memmap")] = NDARRAY
        names[(f"{core}.defmatrix", "matrix")] = MATRIX
    names[("numpy", "ndarray")] = NDARRAY
    names[("numpy", "matrix")] = MATRIX
    names[("numpy", "memmap")] = NDARRAY
    names[("numpy", "dtype")] = Function("numpy.dtype", _dtype)
    for builtins in ("builtins", "__builtin__"):
        for name, function in (("set", lambda v=(): set(_sequence(v))),
                               ("frozenset", lambda v=(): frozenset(_sequence(v))),
                               ("list", lambda v=(): list(_sequence(v))),
                               ("tuple", lambda v=(): tuple(_sequence(v))),
                               ("dict", _dict), ("bytes", _bytes_of),
                               ("bytearray", lambda *a: bytearray(_bytes_of(*a))),
                               ("complex", _complex)):
            names[(builtins, name)] = Function(f"builtins.{name}", function)
        names[(builtins, "object")] = OBJECT
    names[("_codecs", "encode")] = Function("_codecs.encode", _encode)
    for copyreg in ("copyreg", "copy_reg"):
        names[(copyreg, "_reconstructor")] = Function("copyreg._reconstructor", _reconstructor)
    names[("collections", "OrderedDict")] = Function("collections.OrderedDict", _ordered_dict)
    names[("chumpy.ch", "Ch")] = Kind("chumpy.ch.Ch", ChumpyArray)
    for layout in ("csc", "csr", "coo"):
        for module in (f"scipy.sparse.{layout}", f"scipy.sparse._{layout}"):
            for suffix in ("matrix", "array"):
                cls = f"{layout}_{suffix}"
                names[(module, cls)] = Kind(f"{module}.{cls}",
                                            lambda l=layout, c=cls: SparseMatrix(l, c))
    for module in ("joblib.numpy_pickle", "sklearn.externals.joblib.numpy_pickle"):
        names[(module, "NumpyArrayWrapper")] = Kind(f"{module}.NumpyArrayWrapper", JoblibArray)
        names[(module, "NDArrayWrapper")] = Kind(f"{module}.NDArrayWrapper", _old_joblib)
        names[(module, "ZNDArrayWrapper")] = Kind(f"{module}.ZNDArrayWrapper", _old_joblib)
    names[("joblib.numpy_pickle_compat", "NDArrayWrapper")] = Kind("NDArrayWrapper", _old_joblib)
    names[("joblib.numpy_pickle_compat", "ZNDArrayWrapper")] = Kind("ZNDArrayWrapper", _old_joblib)
    return names


NAMES = _names()
