"""Lie-algebra pose parameters and forward/inverse kinematics over kinematic chains.

A pose is (root position, one parameter vector per bone, bone lengths). Bone ``j`` (the
bone ending at joint ``j``) points along its rest direction ``u_j`` turned by the
accumulated rotation ``G_j = G_prev · exp(ŵ_j)``, where ``prev`` is the bone before it
on its kinematic chain (Action2Motion Eq. 4: the product runs inside one chain, so each
chain starts from the identity). ``frames="tree"`` instead continues a branching
chain from the bone that ends at its first joint.

3D: ``w_j ∈ so(3)``, the exponential map is Rodrigues' formula, the log map Eq. 3.
2D has no so(3); a bone gets two numbers ``(θ_j, φ_j)``: ``θ_j ∈ so(2)`` its in-plane
rotation relative to the previous bone of its chain, and ``φ_j`` its tilt out of the
image plane, so its projected length is ``b_j cos φ_j``. Projected 2D skeletons
foreshorten; the tilt lets fixed 3D-like bone lengths ``b_j`` reproduce that.

Rest directions come from data (:func:`rest_directions`), chosen so that few poses
put a bone opposite its rest direction, where the log map is discontinuous: a leg
rests along its mean direction (down), but a hip bone of a person who turns around
rests along the up axis, always about 90 degrees from it.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from motion.skeletons import Skeleton, get_skeleton

# Below this angle the log and exp maps switch to their Taylor expansions.
_SMALL = 1e-4
# Within this of π the log map reads the axis off the symmetric part of R.
_NEAR_PI = 0.05
# Poses beyond 150 degrees from a rest direction count as far (log map near its cut).
_FAR_COS = math.cos(math.radians(150))


def hat(w: torch.Tensor) -> torch.Tensor:
    """Return the skew-symmetric matrices ``(..., 3, 3)`` of vectors ``(..., 3)`` (Eq. 2)."""
    zero = torch.zeros_like(w[..., 0])
    w1, w2, w3 = w.unbind(-1)
    return torch.stack(
        [zero, -w3, w2, w3, zero, -w1, -w2, w1, zero], dim=-1
    ).reshape(w.shape[:-1] + (3, 3))


def so3_exp(w: torch.Tensor) -> torch.Tensor:
    """Map ``so(3)`` vectors ``(..., 3)`` to rotation matrices ``(..., 3, 3)`` (Rodrigues)."""
    theta2 = (w * w).sum(-1)[..., None, None]
    small = theta2 < _SMALL**2
    # Evaluate the closed form on a safe angle so its gradient stays finite at 0.
    safe2 = torch.where(small, torch.ones_like(theta2), theta2)
    safe = safe2.sqrt()
    a = torch.where(small, 1 - theta2 / 6, torch.sin(safe) / safe)
    b = torch.where(small, 0.5 - theta2 / 24, (1 - torch.cos(safe)) / safe2)
    k = hat(w)
    eye = torch.eye(3, dtype=w.dtype, device=w.device)
    return eye + a * k + b * (k @ k)


def so3_log(r: torch.Tensor) -> torch.Tensor:
    """Map rotation matrices ``(..., 3, 3)`` to ``so(3)`` vectors with norm in ``[0, π]`` (Eq. 3)."""
    vee = torch.stack(
        [r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]],
        dim=-1,
    )
    cos = ((r[..., 0, 0] + r[..., 1, 1] + r[..., 2, 2] - 1) / 2).clamp(-1.0, 1.0)
    theta = torch.arccos(cos)[..., None]
    sin = torch.sin(theta)
    small = theta < _SMALL
    general = theta / (2 * torch.where(small, torch.ones_like(sin), sin)) * vee
    w = torch.where(small, (0.5 + theta**2 / 12) * vee, general)
    # Near π, sin θ vanishes and Eq. 3 loses precision: (R + Rᵀ)/2 - cos θ I = (1 - cos θ) n nᵀ.
    near_pi = (theta > math.pi - _NEAR_PI).squeeze(-1)
    if near_pi.any():
        rs, cs, vs, ts = r[near_pi], cos[near_pi], vee[near_pi], theta[near_pi]
        eye = torch.eye(3, dtype=r.dtype, device=r.device)
        outer = ((rs + rs.transpose(-1, -2)) / 2 - cs[..., None, None] * eye) / (
            1 - cs[..., None, None]
        )
        column = outer.diagonal(dim1=-2, dim2=-1).argmax(-1)
        axis = outer[torch.arange(len(rs)), :, column]
        axis = axis / axis.norm(dim=-1, keepdim=True).clamp_min(1e-12)
        sign = torch.where((axis * vs).sum(-1, keepdim=True) < 0, -1.0, 1.0).to(r.dtype)
        w = w.clone()
        w[near_pi] = sign * axis * ts
    return w


def rotation_between(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Return the smallest rotations ``(..., 3, 3)`` taking unit vectors ``u`` to ``v``."""
    u, v = torch.broadcast_tensors(u, v)
    cross = torch.linalg.cross(u, v)
    cos = (u * v).sum(-1)[..., None, None]
    k = hat(cross)
    eye = torch.eye(3, dtype=u.dtype, device=u.device)
    opposite = cos < -1 + 1e-9
    rot = eye + k + (k @ k) / torch.where(opposite, torch.ones_like(cos), 1 + cos)
    if opposite.any():
        # Any half-turn about an axis perpendicular to u takes u to -u.
        basis = torch.eye(3, dtype=u.dtype, device=u.device)[u.abs().argmin(-1)]
        axis = torch.linalg.cross(u, basis)
        axis = axis / axis.norm(dim=-1, keepdim=True)
        half_turn = 2 * axis[..., :, None] * axis[..., None, :] - eye
        rot = torch.where(opposite, half_turn, rot)
    return rot


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Wrap angles to ``(-π, π]``."""
    return torch.atan2(torch.sin(angle), torch.cos(angle))


def _up_vector(skeleton: Skeleton) -> np.ndarray:
    up = np.zeros(skeleton.dims)
    up[skeleton.up_index] = skeleton.up_sign
    return up


def rest_directions(skeleton: Skeleton | str, joints: np.ndarray) -> np.ndarray:
    """Return unit rest directions ``(J, D)`` of the bones from poses ``(..., J, D)``.

    Each bone rests along whichever of its mean direction, the up axis and the down
    axis leaves the fewest poses more than 150 degrees away (ties: the mean). The
    root row is zero.
    """
    skeleton = get_skeleton(skeleton) if isinstance(skeleton, str) else skeleton
    joints = np.asarray(joints, dtype=np.float64).reshape(-1, skeleton.n_joints, skeleton.dims)
    parents = np.array([max(p, 0) for p in skeleton.parents])
    vectors = joints - joints[:, parents]
    norms = np.linalg.norm(vectors, axis=-1, keepdims=True)
    units = np.where(norms > 1e-9, vectors / np.maximum(norms, 1e-12), 0.0)
    up = _up_vector(skeleton)
    rest = np.zeros((skeleton.n_joints, skeleton.dims))
    for j in range(skeleton.n_joints):
        if j == skeleton.root:
            continue
        mean = units[:, j].mean(axis=0)
        length = np.linalg.norm(mean)
        candidates = ([mean / length] if length > 1e-6 else []) + [up, -up]
        far = [np.mean(units[:, j] @ c < _FAR_COS) for c in candidates]
        rest[j] = candidates[int(np.argmin(far))]
    return rest


def clip_bone_lengths(skeleton: Skeleton | str, joints: np.ndarray) -> np.ndarray:
    """Return the bone lengths ``(..., J)`` of clips ``(..., T, J, D)`` (root: 0).

    3D: the median over frames. 2D: the maximum over frames, the least foreshortened
    view, so every projected length is ``b cos φ`` for some tilt ``φ``.
    """
    skeleton = get_skeleton(skeleton) if isinstance(skeleton, str) else skeleton
    lengths = skeleton.bone_lengths(np.asarray(joints, dtype=np.float64))
    if skeleton.dims == 2:
        return lengths.max(axis=-2)
    return np.median(lengths, axis=-2)


class Kinematics:
    """Forward and inverse kinematics of one skeleton with fixed rest directions."""

    def __init__(self, skeleton: Skeleton | str, rest: np.ndarray, frames: str = "chain"):
        self.skeleton = get_skeleton(skeleton) if isinstance(skeleton, str) else skeleton
        if frames not in ("chain", "tree"):
            raise ValueError(f"frames must be 'chain' (A2M Eq. 4) or 'tree'; got {frames!r}")
        skel = self.skeleton
        rest = np.asarray(rest, dtype=np.float64)
        if rest.shape != (skel.n_joints, skel.dims):
            raise ValueError(
                f"rest directions must have shape {(skel.n_joints, skel.dims)} for skeleton "
                f"{skel.name!r}; got {rest.shape}"
            )
        self.dims = skel.dims
        self.param_size = 3 if skel.dims == 3 else 2
        self.frames = frames
        self.parents = skel.parents
        self.root = skel.root
        # Parameters are laid out per bone in joint order (root excluded), as in Table 3.
        self.bone_joints = tuple(j for j in range(skel.n_joints) if j != skel.root)
        self._bone_of = {j: b for b, j in enumerate(self.bone_joints)}
        self.previous = self._previous_bones(frames)
        self.order = self._topological_order()
        self.rest = torch.as_tensor(rest)
        self.rest_angle = torch.atan2(self.rest[:, 1], self.rest[:, 0]) if skel.dims == 2 else None

    @property
    def n_bones(self) -> int:
        return len(self.bone_joints)

    @property
    def n_params(self) -> int:
        """Return the number of pose parameters of one frame (root excluded)."""
        return self.n_bones * self.param_size

    def _previous_bones(self, frames: str) -> dict[int, int]:
        """Map each joint to the joint whose bone rotation it composes onto (-1: none)."""
        previous = {}
        if frames == "tree":
            for j in self.bone_joints:
                p = self.parents[j]
                previous[j] = -1 if p == self.root else p
            return previous
        for chain in self.skeleton.chains:
            for k in range(1, len(chain)):
                previous[chain[k]] = chain[k - 1] if k >= 2 else -1
        missing = set(self.bone_joints) - set(previous)
        if missing:
            raise ValueError(
                f"skeleton {self.skeleton.name!r}: joints {sorted(missing)} are on no "
                f"kinematic chain; fix its chains or use frames='tree'"
            )
        return previous

    def _topological_order(self) -> list[int]:
        depth = {self.root: 0}

        def depth_of(j):
            if j not in depth:
                depth[j] = depth_of(self.parents[j]) + 1
            return depth[j]

        return sorted(self.bone_joints, key=depth_of)

    def _lengths(self, lengths, like: torch.Tensor) -> torch.Tensor:
        lengths = torch.as_tensor(lengths, dtype=like.dtype, device=like.device)
        if lengths.shape[-1] != self.skeleton.n_joints:
            raise ValueError(
                f"bone lengths must end in {self.skeleton.n_joints} (one per joint of "
                f"{self.skeleton.name!r}, root ignored); got shape {tuple(lengths.shape)}"
            )
        return lengths

    def forward(self, params: torch.Tensor, root: torch.Tensor, lengths) -> torch.Tensor:
        """Return joints ``(..., J, D)`` from parameters ``(..., bones, P)``, root ``(..., D)``.

        ``lengths`` is ``(J,)`` or broadcastable ``(..., J)``, in joint order.
        """
        lengths = self._lengths(lengths, params)
        rest = self.rest.to(params.dtype)
        positions: list[torch.Tensor | None] = [None] * self.skeleton.n_joints
        positions[self.root] = root
        turned: dict[int, torch.Tensor] = {}
        if self.dims == 3:
            local = so3_exp(params)
        for j in self.order:
            b = self._bone_of[j]
            prev = self.previous[j]
            if self.dims == 3:
                rot = local[..., b, :, :] if prev < 0 else turned[prev] @ local[..., b, :, :]
                turned[j] = rot
                step = (rot @ rest[j]) * lengths[..., j, None]
            else:
                angle = params[..., b, 0] if prev < 0 else turned[prev] + params[..., b, 0]
                turned[j] = angle
                world = angle + self.rest_angle[j].to(params.dtype)
                scale = lengths[..., j] * torch.cos(params[..., b, 1])
                step = torch.stack([torch.cos(world), torch.sin(world)], dim=-1) * scale[..., None]
            positions[j] = positions[self.parents[j]] + step
        return torch.stack(positions, dim=-2)

    @torch.no_grad()
    def inverse(self, joints: torch.Tensor, lengths=None) -> tuple[torch.Tensor, torch.Tensor]:
        """Return ``(params (..., bones, P), root (..., D))`` of joints ``(..., J, D)``.

        3D ignores ``lengths``. 2D needs them (``(J,)`` or ``(..., J)``) to read each
        bone's tilt from its projected length; lengths shorter than a bone clip at tilt 0.
        """
        joints = torch.as_tensor(joints)
        parents = torch.tensor([max(p, 0) for p in self.parents])
        vectors = joints - joints[..., parents, :]
        norms = vectors.norm(dim=-1, keepdim=True)
        rest = self.rest.to(joints.dtype)
        params = joints.new_zeros(joints.shape[:-2] + (self.n_bones, self.param_size))
        turned: dict[int, torch.Tensor] = {}
        if self.dims == 2:
            if lengths is None:
                raise ValueError("2D inverse kinematics needs bone lengths to read bone tilts")
            lengths = self._lengths(lengths, joints)
        for j in self.order:
            b = self._bone_of[j]
            prev = self.previous[j]
            degenerate = norms[..., j, :] < 1e-9
            if self.dims == 3:
                # A zero-length bone has no direction; keep it at rest.
                unit = torch.where(degenerate, rest[j], vectors[..., j, :] / norms[..., j, :].clamp_min(1e-12))
                rot = rotation_between(rest[j].expand_as(unit), unit)
                local = rot if prev < 0 else turned[prev].transpose(-1, -2) @ rot
                turned[j] = rot
                params[..., b, :] = so3_log(local)
            else:
                vec = vectors[..., j, :]
                angle = torch.atan2(vec[..., 1], vec[..., 0]) - self.rest_angle[j].to(joints.dtype)
                angle = torch.where(degenerate[..., 0], torch.zeros_like(angle), wrap_angle(angle))
                local = angle if prev < 0 else wrap_angle(angle - turned[prev])
                turned[j] = angle
                ratio = norms[..., j, 0] / lengths[..., j].clamp_min(1e-12)
                params[..., b, 0] = local
                params[..., b, 1] = torch.arccos(ratio.clamp(0.0, 1.0))
        return params, joints[..., self.root, :].clone()
