"""The files data comes in: ``.npy``, ``.npz``, pickles and joblib's files, compressed or not.

- ``.npy``: numpy's header (``numpy.lib.format``), then the array's bytes, or, for an
  array of objects, a pickle of it, read by the restricted unpickler;
- ``.npz``: a zip of ``.npy`` members, each read as above;
- a pickle (``.pkl``, ``.pickle``, ``.p``, ...) or joblib's file: joblib writes a pickle
  in which each array is a ``NumpyArrayWrapper`` followed by the array's bytes, the whole
  stream compressed with zlib, gzip, bz2, xz or lzma (or lz4, if installed) when asked;
  the compression is recognised by its magic number, as joblib does.
"""

from __future__ import annotations

import bz2
import gzip
import io
import lzma
import zipfile
import zlib
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

from motion.safe_load import data_types, torch_data
from motion.safe_load.unpickler import DataFileError, unpickle

NAMES = {**data_types.NAMES, **torch_data.NAMES}
NPY_MAGIC = b"\x93NUMPY"
ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
JOBLIB_OLD = b"ZF"  # joblib < 0.10: arrays in files beside the pickle


def _opened(path: Path):
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"{path} does not exist (or is not a file)")
    return open(path, "rb")


# --- numpy -----------------------------------------------------------------------------------


def _header(handle, source: str):
    """Return ``(shape, fortran_order, dtype)`` of the ``.npy`` stream at ``handle``."""
    try:
        version = npy_format.read_magic(handle)
        # Version 3.0 differs from 2.0 only in its header's encoding (UTF-8 field names).
        read = npy_format.read_array_header_1_0 if version == (1, 0) else \
            npy_format.read_array_header_2_0
        return read(handle)
    except Exception as exc:  # numpy raises ValueError, OSError, SyntaxError, ...
        raise DataFileError(f"{source} is not a readable .npy file ({exc})") from None


def read_npy(handle, source: str) -> np.ndarray:
    """Return the array of the ``.npy`` stream at ``handle`` (seekable), objects included."""
    start = handle.tell()
    shape, _, dtype = _header(handle, source)
    if not dtype.hasobject:
        handle.seek(start)
        try:
            return npy_format.read_array(handle, allow_pickle=False)
        except Exception as exc:
            raise DataFileError(f"{source} is not a readable .npy file ({exc})") from None
    array = unpickle(handle, source, NAMES)
    if not isinstance(array, np.ndarray) or array.shape != tuple(shape):
        raise DataFileError(f"{source}: its header promises an array of shape {tuple(shape)}; "
                            f"its pickle holds {getattr(array, 'shape', type(array).__name__)}")
    return array


def load_npy(path) -> np.ndarray:
    """Return the array of a ``.npy`` file; an array of objects holds plain data only."""
    with _opened(path) as handle:
        return read_npy(handle, str(path))


def npy_header(path) -> tuple[tuple[int, ...], np.dtype]:
    """Return the shape and dtype of a ``.npy`` file without reading its data."""
    with _opened(path) as handle:
        shape, _, dtype = _header(handle, str(path))
    return tuple(shape), dtype


def _archive(handle, path) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(handle)
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise DataFileError(f"{path} is not a readable .npz file ({exc})") from None


def npz_names(path) -> list[str]:
    """Return the names of a ``.npz`` file's arrays (``np.load``'s keys), reading none."""
    with _opened(path) as handle, _archive(handle, path) as archive:
        return [name[:-4] if name.endswith(".npy") else name for name in archive.namelist()]


def load_npz(path, only=None) -> dict:
    """Return the arrays of a ``.npz`` file by name (``np.load``'s keys; ``only`` these);
    members that are not ``.npy`` files are returned as their bytes."""
    path = Path(path)
    out = {}
    with _opened(path) as handle, _archive(handle, path) as archive:
        for name in archive.namelist():
            key = name[:-4] if name.endswith(".npy") else name
            if only is not None and key not in only:
                continue
            source = f"{path} (member {name})"
            try:
                with archive.open(name) as member:
                    magic = member.read(len(NPY_MAGIC))
                    if magic != NPY_MAGIC:
                        out[key] = magic + member.read()
                        continue
                with archive.open(name) as member:
                    out[key] = read_npy(member, source)
            except (zipfile.BadZipFile, OSError, EOFError, zlib.error) as exc:
                raise DataFileError(f"{source} cannot be read ({exc})") from None
    return out


# --- pickles and joblib ------------------------------------------------------------------------


class _ZlibReader(io.RawIOBase):
    """joblib's zlib files: one zlib stream, decompressed as it is read."""

    CHUNK = 1 << 16

    def __init__(self, file):
        super().__init__()
        self.file, self.inflate = file, zlib.decompressobj()

    def readable(self):
        return True

    def readinto(self, buffer):
        while True:
            if self.inflate.unconsumed_tail:
                data = self.inflate.decompress(self.inflate.unconsumed_tail, len(buffer))
            elif self.inflate.eof:
                return 0
            else:
                chunk = self.file.read(self.CHUNK)
                if not chunk:
                    return 0
                data = self.inflate.decompress(chunk, len(buffer))
            if data:
                buffer[: len(data)] = data
                return len(data)


def _lz4(handle):
    try:
        import lz4.frame
    except ImportError:
        raise DataFileError("compressed with lz4, which is not installed: pip install lz4, "
                            "or save the file with another compression") from None
    return lz4.frame.LZ4FrameFile(handle)


COMPRESSIONS = (  # joblib's magic numbers, in the order joblib tries them
    (b"x", "zlib", lambda h: io.BufferedReader(_ZlibReader(h), 1 << 20)),
    (b"\x1f\x8b", "gzip", lambda h: gzip.GzipFile(fileobj=h)),
    (b"BZ", "bz2", bz2.BZ2File),
    (b"\xfd7zXZ", "xz", lzma.LZMAFile),
    (b"]\x00", "lzma", lzma.LZMAFile),
    (b'\x04"M\x18', "lz4", _lz4),
)


def load_pickle(path):
    """Return the plain data of a pickle or joblib file (compressed or not)."""
    source = str(path)
    with _opened(path) as handle:
        head = handle.peek(8)[:8]
        if head.startswith(JOBLIB_OLD):
            raise DataFileError(f"{source}: written by joblib older than 0.10, which kept its "
                                "arrays in files beside it; load it with that joblib where you "
                                "trust it and save the arrays with numpy.savez")
        stream, compression = handle, None
        for magic, name, opener in COMPRESSIONS:
            if head.startswith(magic):
                try:
                    stream, compression = opener(handle), name
                except DataFileError as exc:
                    raise DataFileError(f"{source}: {exc}") from None
                break
        try:
            return unpickle(stream, source, NAMES)
        except DataFileError as exc:
            if compression and "not a readable pickle" in str(exc):
                raise DataFileError(f"{exc}; it looked {compression}-compressed") from None
            raise


def load_data(path):
    """Return the plain data of a ``.npy``, ``.npz``, pickle or joblib file (by content).

    Nothing in the file is run: only plain data is built (see
    :mod:`motion.safe_load`); anything else raises :class:`DataFileError` naming the
    file and what it asked for.
    """
    with _opened(path) as handle:
        head = handle.peek(8)[:8]
    if head.startswith(NPY_MAGIC):
        return load_npy(path)
    if head.startswith(ZIP_MAGIC):
        return load_npz(path)
    return load_pickle(path)
