"""Torch tensors inside pickles (e.g. PHC's joblib motion libraries), read as numpy arrays.

torch pickles a tensor as ``torch._utils._rebuild_tensor_v2(storage, offset, size,
stride, requires_grad, hooks[, metadata])`` (a parameter wraps that in
``_rebuild_parameter``), and the storage as ``torch.storage._load_from_bytes(b)``, where
``b`` is torch's legacy (non-zip) ``torch.save`` of that one storage: five pickles (a
magic number, the protocol version 1001, ``sys_info`` with the byte order, the storage
as a persistent id ``("storage", torch.FloatStorage, key, location, numel[, view])``,
the list of keys), then per key its element count (int64) and raw bytes. torch's own
loader for ``b`` unpickles anything (it turns off ``weights_only``); here ``b`` is parsed
as that layout with the same restricted reader, and torch is never imported.
"""

from __future__ import annotations

import io
import struct

import numpy as np

from motion.safe_load.unpickler import DataFileError, DataUnpickler, Function, Marker

MAGIC, PROTOCOL = 0x1950A86A20F9469CFC6C, 1001
BFLOAT16 = "bfloat16"
STORAGES = {
    "FloatStorage": "f4", "DoubleStorage": "f8", "HalfStorage": "f2", "BFloat16Storage": BFLOAT16,
    "LongStorage": "i8", "IntStorage": "i4", "ShortStorage": "i2", "CharStorage": "i1",
    "ByteStorage": "u1", "BoolStorage": "?", "ComplexFloatStorage": "c8",
    "ComplexDoubleStorage": "c16",
}
STORAGE_NAMES = {("torch", name): Marker(f"torch.{name}") for name in STORAGES}


class TorchStorage:
    """A torch storage's elements as a flat numpy array (only a tensor's argument)."""

    name = "torch storage"

    def __init__(self, array: np.ndarray):
        self.array = array


def _element_dtype(marker, little: bool) -> tuple[np.dtype, bool]:
    """Return the numpy dtype of a storage type's raw elements, and whether it is bfloat16."""
    code = STORAGES[marker.name.split(".", 1)[1]]
    order = "<" if little else ">"
    if code == BFLOAT16:
        return np.dtype(order + "u2"), True
    return np.dtype(code if code in ("i1", "u1", "?") else order + code), False


def load_from_bytes(data) -> TorchStorage:
    """Return the storage in torch's legacy serialisation ``data`` (see the module doc)."""
    if not isinstance(data, bytes):
        raise TypeError("a storage is read from bytes")
    stream = io.BytesIO(data)
    pending = []

    def storage(pid):
        if (not isinstance(pid, tuple) or len(pid) not in (5, 6) or pid[0] != "storage"
                or pid[1] not in STORAGE_NAMES.values() or not isinstance(pid[2], str)):
            raise DataFileError(f"a torch storage reference {pid!r:.80} is not one")
        pending.append(pid)
        return pid

    def read(names=None, persistent=None):
        return DataUnpickler(stream, "a torch storage", names or {}, persistent).load()

    if read() != MAGIC or read() != PROTOCOL:
        raise DataFileError("a torch storage not in torch's legacy layout (magic number 0x1950a8"
                            "6a20f9469cfc6c, protocol 1001)")
    info = read()
    little = not isinstance(info, dict) or info.get("little_endian", True)
    root = read(STORAGE_NAMES, storage)
    keys = read()
    if not pending or root is not pending[0] or not isinstance(keys, list):
        raise DataFileError("a torch storage pickle that holds no storage")
    types = {pid[2]: pid[1] for pid in pending}
    arrays = {}
    for key in keys:
        if key not in types or key in arrays:
            raise DataFileError(f"a torch storage key {key!r:.40} is not one")
        head = stream.read(8)
        if len(head) != 8:
            raise DataFileError("a torch storage is cut short")
        (count,) = struct.unpack("<q" if little else ">q", head)
        dtype, bfloat = _element_dtype(types[key], little)
        raw = stream.read(count * dtype.itemsize) if count >= 0 else b""
        if count < 0 or len(raw) != count * dtype.itemsize:
            raise DataFileError(f"a torch storage of {count} elements is cut short")
        values = np.frombuffer(raw, dtype)
        if bfloat:  # bfloat16 is the upper half of a float32
            values = (values.astype(np.uint32) << 16).view(np.float32)
        arrays[key] = values.astype(values.dtype.newbyteorder("="))
    _, _, key, _, *rest = root
    if key not in arrays:
        raise DataFileError(f"a torch storage's data for key {key!r:.40} is missing")
    array = arrays[key]
    view = rest[-1] if rest else None
    if view is not None:  # old torch: (view key, offset, size) of a view of a storage
        if not (isinstance(view, tuple) and len(view) == 3 and all(isinstance(v, int)
                                                                   for v in view[1:])):
            raise DataFileError("a torch storage view that is not one")
        _, offset, size = view
        if offset < 0 or size < 0 or offset + size > len(array):
            raise DataFileError("a torch storage view beyond its storage")
        array = array[offset: offset + size]
    return TorchStorage(array)


def _ints(value, what: str) -> tuple[int, ...]:
    if not isinstance(value, (tuple, list)) or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise ValueError(f"a tensor's {what} is not a tuple of integers")
    return tuple(value)


def rebuild_tensor(storage, offset, size, stride, *_rest):
    """Return the tensor of ``size`` and ``stride`` from ``offset`` of ``storage`` as an array."""
    if not isinstance(storage, TorchStorage):
        raise TypeError("a tensor is rebuilt from a torch storage")
    size, stride = _ints(size, "size"), _ints(stride, "stride")
    if not isinstance(offset, int) or offset < 0 or len(size) != len(stride):
        raise ValueError("a tensor's offset, size and stride do not match")
    if any(n < 0 for n in size) or any(s < 0 for s in stride):
        raise ValueError("a tensor's size and stride must not be negative")
    flat = storage.array
    if 0 in size:
        return np.empty(size, flat.dtype)
    last = offset + sum((n - 1) * s for n, s in zip(size, stride))
    if last >= len(flat):
        raise ValueError(f"a tensor reaches element {last} of a storage of {len(flat)}")
    view = np.lib.stride_tricks.as_strided(flat[offset:], shape=size,
                                           strides=[s * flat.itemsize for s in stride])
    return view.copy()


def rebuild_parameter(data, requires_grad=False, hooks=None, state=None):
    """Return a parameter's data (already an array)."""
    if not isinstance(data, np.ndarray):
        raise TypeError("a parameter wraps a tensor")
    return data


NAMES = {
    ("torch._utils", "_rebuild_tensor_v2"): Function("torch._utils._rebuild_tensor_v2",
                                                     rebuild_tensor),
    ("torch._utils", "_rebuild_tensor"): Function("torch._utils._rebuild_tensor", rebuild_tensor),
    ("torch._utils", "_rebuild_parameter"): Function("torch._utils._rebuild_parameter",
                                                     rebuild_parameter),
    ("torch._utils", "_rebuild_parameter_with_state"): Function(
        "torch._utils._rebuild_parameter_with_state", rebuild_parameter),
    ("torch.storage", "_load_from_bytes"): Function("torch.storage._load_from_bytes",
                                                    load_from_bytes),
}
