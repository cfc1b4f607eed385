"""Datasets of real (and one synthetic) motion, in a registry.

``get_dataset("h36m").clips()`` gives fixed-length clips; importing this package
registers ``demo``, ``h36m``, ``h36m2d``, ``humanact12``, ``humanml3d`` and ``kit_ml``
(the registry imports every module of this package before its first lookup).
"""

from motion.datasets.base import (
    Dataset,
    DatasetError,
    LoadReport,
    get_dataset,
    list_datasets,
    register_dataset,
)

__all__ = ["Dataset", "DatasetError", "LoadReport", "get_dataset", "list_datasets",
           "register_dataset"]
