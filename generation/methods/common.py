"""Torch and numpy helpers shared by the methods: placement, normalisation, losses, pose vectors."""

from __future__ import annotations

import numpy as np
import torch

from motion.skeletons import Skeleton, get_skeleton

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


def relative_to_start(skeleton: Skeleton, joints: np.ndarray) -> np.ndarray:
    """Return clips ``(N, T, J, D)`` minus their :func:`horizontal_start`.

    Each then begins above the origin, at its own height (or image row in 2D).
    """
    return joints - horizontal_start(skeleton, joints)[:, None, None]


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


def adam(modules, lr: float, betas: tuple[float, float],
         weight_decay: float = 0.0) -> torch.optim.Adam:
    """Return one Adam over the parameters of several modules."""
    params = [p for module in modules for p in module.parameters()]
    return torch.optim.Adam(params, lr=lr, betas=betas, weight_decay=weight_decay)


# Pose vectors: the representation of the GAN and VAE baselines. A pose is the joint
# positions relative to its clip's horizontal start, flattened to ``F = J * D`` numbers
# and standardised per coordinate over the training frames; generated poses are placed
# at the training clips' mean start. The statistics are a dict ``{"origin", "mean",
# "std"}``, which the methods keep (and save) as their ``extras``.


def pose_statistics(skeleton: Skeleton, joints: np.ndarray) -> dict:
    """Return the placement and scaling of clips ``(N, T, J, D)``: origin, mean and std.

    ``origin`` ``(D,)`` is the clips' mean horizontal start; ``mean`` and ``std`` are per
    coordinate of the flattened pose ``(F,)``.
    """
    starts = horizontal_start(skeleton, joints)
    flat = (joints - starts[:, None, None]).reshape(-1, skeleton.n_joints * skeleton.dims)
    mean, std = mean_std(flat, floor=1e-3 * float(flat.std()) + 1e-9)
    return {"origin": starts.mean(axis=0), "mean": mean, "std": std}


def standardise_poses(relative: np.ndarray, stats: dict) -> np.ndarray:
    """Return standardised pose vectors ``(..., F)`` of start-relative poses ``(..., J, D)``."""
    flat = relative.reshape(relative.shape[:-2] + (-1,))
    return (flat - stats["mean"]) / stats["std"]


def pose_vectors(skeleton: Skeleton, joints: np.ndarray, stats: dict) -> torch.Tensor:
    """Return the standardised pose vectors ``(N, T, F)`` float32 of clips ``(N, T, J, D)``."""
    return torch.from_numpy(standardise_poses(relative_to_start(skeleton, joints), stats)).float()


def unstandardise_poses(skeleton: Skeleton, poses: torch.Tensor, stats: dict) -> np.ndarray:
    """Return start-relative joints ``(N, T, J, D)`` float64 of pose vectors ``(N, T, F)``."""
    flat = poses.double().numpy() * stats["std"] + stats["mean"]
    return flat.reshape(poses.shape[:2] + (skeleton.n_joints, skeleton.dims))


def place_poses(skeleton: Skeleton, poses: torch.Tensor, stats: dict) -> np.ndarray:
    """Return joints ``(N, T, J, D)`` float32 of pose vectors ``(N, T, F)``, at the origin."""
    joints = unstandardise_poses(skeleton, poses, stats)
    return (joints + np.asarray(stats["origin"])).astype(np.float32)


class PoseVectors:
    """Mixin for methods that model motions as pose vectors (see :func:`pose_statistics`).

    It implements the data hooks of :class:`~generation.methods.base.Method`:
    :meth:`prepare` keeps the pose statistics in ``extras``, :meth:`encode` gives the
    clips' pose vectors ``"pose"`` ``(N, T, F)`` and action indices ``"label"`` ``(N,)``;
    ``generate`` turns its pose vectors into joints with :meth:`poses_to_joints`. List
    it before ``Method`` in the bases.
    """

    def prepare(self, clips):
        """Return the pose statistics of the training clips (origin, mean, std)."""
        return pose_statistics(get_skeleton(self.skeleton), self.clip_array(clips))

    def encode(self, clips):
        """Return the clips' pose vectors and action indices."""
        return {
            "pose": pose_vectors(get_skeleton(self.skeleton), self.clip_array(clips), self.extras),
            "label": self.action_indices([clip.action for clip in clips]),
        }

    def poses_to_joints(self, poses: torch.Tensor) -> np.ndarray:
        """Return joints ``(N, T, J, D)`` float32 of generated pose vectors ``(N, T, F)``."""
        return place_poses(get_skeleton(self.skeleton), poses, self.extras)


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
