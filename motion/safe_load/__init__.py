"""Read data files that other people send without running anything in them.

A pickle, and so an ``.npy`` of objects, an ``.npz`` member of objects, a ``.pkl`` or a
joblib file, can name any function for the reader to call, and numpy's loader (when
allowed pickles), ``pickle`` and ``joblib`` call it. :func:`load_data` reads all of these with a
restricted unpickler that only builds plain data: numpy arrays, dtypes and scalars,
numbers, strings, bytes, None, lists, tuples, dicts, sets and OrderedDicts, and, as
arrays, chumpy's ``Ch`` (official SMPL files), scipy's sparse matrices, torch tensors
(torch is never imported) and joblib's arrays. Any other name raises
:class:`RefusedObject` naming the file and the ``module.qualname`` it asked for, before
anything of it is called.

    load_data(path)   -> the file's data (by content: .npy, .npz, else a pickle/joblib file)
    load_npy(path)    -> np.ndarray        npy_header(path) -> (shape, dtype)
    load_npz(path)    -> {name: array}     npz_names(path) -> [name, ...]
    load_pickle(path) -> data

Product code reads every user file through these; ``tests/test_safe_imports.py`` checks
that no product module unpickles any other way.
"""

from motion.safe_load.files import (
    load_data,
    load_npy,
    load_npz,
    load_pickle,
    npy_header,
    npz_names,
)
from motion.safe_load.unpickler import DataFileError, RefusedObject

__all__ = ["DataFileError", "RefusedObject", "load_data", "load_npy", "load_npz", "load_pickle",
           "npy_header", "npz_names"]
