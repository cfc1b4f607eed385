"""CondGRU, the deterministic baseline of Action2Motion (seed 000, Sec. 4.2.2).

A conditional GRU reads the action (one-hot) and the previous pose and outputs the next
pose; it is trained with teacher forcing on real clips. It cannot start by itself: a
sample begins with the first pose of a training clip of its action, chosen by the seed
from a bank of first poses kept in the checkpoint (as in seed 000, where "the first
frame is required as part of the input"). The paper gives no sizes; we take the A2M
generator's (encoder 128, 2-layer GRU of 128) and its optimiser settings.

Poses are joint positions relative to the clip's first root position on the floor
(height kept), standardised per coordinate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
from torch import nn

from generation.methods.base import Method, MethodConfig, MethodError, register_method
from generation.methods.common import (
    PoseVectors,
    horizontal_start,
    one_hot,
    standardise_poses,
    unstandardise_poses,
)
from motion.skeletons import get_skeleton


@dataclass
class CondGRUConfig(MethodConfig):
    """CondGRU hyper-parameters (sizes and optimiser as A2M's generator)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "demo": {"hidden": 64, "batch_size": 32, "lr": 1e-3},
        "tiny": {"hidden": 16, "batch_size": 8},
    }

    batch_size: int = 128
    hidden: int = 128
    layers: int = 2
    lr: float = 2e-4
    weight_decay: float = 1e-5
    first_poses: int = 256  # first poses kept per action for sampling

    def validate(self) -> None:
        super().validate()
        if min(self.hidden, self.layers, self.first_poses) < 1:
            raise ValueError("CondGRUConfig hidden, layers and first_poses must be >= 1")


class ConditionalGRU(nn.Module):
    """(pose_{t-1}, action) -> encoder -> GRU -> decoder -> pose_t."""

    def __init__(self, pose: int, classes: int, hidden: int, layers: int):
        super().__init__()
        self.encoder = nn.Linear(pose + classes, hidden)
        self.gru = nn.GRU(hidden, hidden, num_layers=layers, batch_first=True)
        self.decoder = nn.Linear(hidden, pose)

    def forward(self, poses: torch.Tensor, classes: torch.Tensor, state=None):
        """Return next poses ``(B, T, F)`` of poses ``(B, T, F)`` and classes ``(B, C)``."""
        condition = classes[:, None, :].expand(-1, poses.shape[1], -1)
        hidden, state = self.gru(self.encoder(torch.cat([poses, condition], dim=-1)), state)
        return self.decoder(hidden), state


@register_method("cond_gru")
class CondGRU(PoseVectors, Method):
    """Conditional GRU: deterministic, starts from a real first pose of the action."""

    Config = CondGRUConfig

    def build(self):
        return {"gru": ConditionalGRU(self.pose_width, len(self.actions), self.config.hidden,
                                      self.config.layers)}

    def build_optimizers(self):
        return {"adam": torch.optim.Adam(self.networks["gru"].parameters(), lr=self.config.lr,
                                         weight_decay=self.config.weight_decay)}

    def prepare(self, clips):
        """Return the poses' mean and std, and a bank of first poses per action."""
        skeleton = get_skeleton(self.skeleton)
        stats = super().prepare(clips)  # its origin is unused: samples start at real poses
        bank = {}
        for action in self.actions:
            firsts = np.array([clip.joints[0] for clip in clips if clip.action == action],
                              dtype=np.float32)
            if len(firsts) > self.config.first_poses:
                # Keep poses spread over the clips rather than the first ones (often one subject).
                pick = np.linspace(0, len(firsts) - 1, self.config.first_poses).round().astype(int)
                firsts = firsts[pick]
            bank[action] = firsts.reshape(-1, skeleton.n_joints, skeleton.dims)
        return {"mean": stats["mean"], "std": stats["std"], "first_poses": bank}

    def train_step(self, batch, generator):
        pose = batch["pose"]
        classes = one_hot(batch["label"], len(self.actions))
        predicted, _ = self.networks["gru"](pose[:, :-1], classes)
        loss = ((predicted - pose[:, 1:]) ** 2).mean()
        optimizer = self.optimizers["adam"]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        return {"mse": loss.item()}

    def first_pose_choices(self, labels: torch.Tensor, generator: torch.Generator) -> np.ndarray:
        """Return one first pose ``(N, J, D)`` per label, drawn from the bank of its action."""
        bank = self.extras["first_poses"]
        poses = []
        for label in labels.tolist():
            action = self.actions[label]
            firsts = bank.get(action)
            if firsts is None or len(firsts) == 0:
                known = [a for a in self.actions if len(bank.get(a, ())) > 0]
                raise MethodError(
                    f"cond_gru has no first pose of action {action!r}: its training clips had "
                    f"none. Sample one of {', '.join(known)} or train with clips of {action!r}"
                )
            poses.append(firsts[int(torch.randint(len(firsts), (1,), generator=generator))])
        return np.stack(poses).astype(np.float64)

    def generate(self, labels, frames, generator):
        skeleton = get_skeleton(self.skeleton)
        first = self.first_pose_choices(labels, generator)
        start = horizontal_start(skeleton, first[:, None])
        classes = one_hot(labels, len(self.actions))
        standardised = standardise_poses(first - start[:, None], self.extras)
        pose = torch.from_numpy(standardised).float()[:, None]
        outputs, state = [pose], None
        net = self.networks["gru"]
        for _ in range(frames - 1):
            pose, state = net(pose, classes, state)
            outputs.append(pose)
        relative = unstandardise_poses(skeleton, torch.cat(outputs, dim=1), self.extras)
        joints = relative + start[:, None, None]
        joints[:, 0] = first  # exactly the real first pose, not its normalised round trip
        return joints.astype(np.float32)
