"""Torch and numpy helpers shared by the methods: placement, normalisation, losses."""

from __future__ import annotations

import numpy as np
import torch

from generation.skeletons import Skeleton

# 2D data are in pixels; losses tuned in metres (A2M's λ) see them rescaled so that the
# mean bone is this long, about that of a Human3.6M body.
REFERENCE_BONE_METRES = 0.25


def horizontal_start(skeleton: Skeleton, joints: np.ndarray) -> np.ndarray:
    """Return each clip's first root position with the up coordinate zeroed, ``(N, D)``.

    Clips ``(N, T, J, D)`` minus this start keep their height above the floor (or their
    image row in 2D) but begin above the origin.
    """
    start = np.array(joints[:, 0, skeleton.root, :], dtype=np.float64)
    start[:, skeleton.up_index] = 0.0
    return start


def loss_unit(skeleton: Skeleton, bone_lengths: np.ndarray) -> float:
    """Return the length that losses divide by: 1 for metres (3D), else pixels per metre."""
    if skeleton.dims == 3:
        return 1.0
    mean_bone = float(np.mean(np.delete(bone_lengths, skeleton.root)))
    return max(mean_bone / REFERENCE_BONE_METRES, 1e-6)


def mean_std(values: np.ndarray, floor: float) -> tuple[np.ndarray, np.ndarray]:
    """Return mean and standard deviation over the first axis, the std at least ``floor``."""
    values = np.asarray(values, dtype=np.float64)
    return values.mean(axis=0), np.maximum(values.std(axis=0), floor)


def one_hot(labels: torch.Tensor, classes: int) -> torch.Tensor:
    """Return float one-hot rows ``(N, classes)`` of integer labels ``(N,)``."""
    return torch.nn.functional.one_hot(labels, classes).float()


def gaussian_kl(mu_q, logvar_q, mu_p, logvar_p) -> torch.Tensor:
    """Return KL(N_q || N_p) of diagonal Gaussians, summed over dimensions, mean over the batch."""
    kl = 0.5 * (logvar_p - logvar_q) + (logvar_q.exp() + (mu_q - mu_p) ** 2) / (
        2 * logvar_p.exp()
    ) - 0.5
    return kl.sum(-1).mean()


def to_tensors(tree):
    """Return a copy of nested dicts/lists with numpy arrays as torch tensors (for saving)."""
    if isinstance(tree, dict):
        return {key: to_tensors(value) for key, value in tree.items()}
    if isinstance(tree, (list, tuple)):
        return [to_tensors(value) for value in tree]
    if isinstance(tree, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(tree))
    if isinstance(tree, np.generic):
        return tree.item()
    return tree


def to_arrays(tree):
    """Return a copy of nested dicts/lists with torch tensors as numpy arrays (after loading)."""
    if isinstance(tree, dict):
        return {key: to_arrays(value) for key, value in tree.items()}
    if isinstance(tree, (list, tuple)):
        return [to_arrays(value) for value in tree]
    if isinstance(tree, torch.Tensor):
        return tree.numpy()
    return tree
