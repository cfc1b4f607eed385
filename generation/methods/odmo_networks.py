"""ODMO's networks (seed 001, Table S2): LMP encoder, trajectory generator, motion generator.

Two options, not in the paper, make trajectory customisation hold at any training budget
(see :mod:`generation.methods.odmo`): with ``exact_end`` the trajectory generator's last
step spreads the miss ``r_e - Σ v̂`` evenly over its velocities, so the path ends exactly
at ``r_e``; with ``about_path`` the motion decoder predicts each pose about the guide
point ``r̂_t`` (a skip connection).
"""

from __future__ import annotations

import torch
from torch import nn


class LMPEncoder(nn.Module):
    """LMP ``(B, T, F)`` -> LSTM -> (FC + BN + PReLU) × 2 -> FC -> (μ, log σ²)."""

    def __init__(self, inputs: int, hidden: int, feature: int, latent: int):
        super().__init__()
        self.lstm = nn.LSTM(inputs, hidden, batch_first=True)
        self.head = nn.Sequential(
            nn.Linear(hidden, feature), nn.BatchNorm1d(feature), nn.PReLU(),
            nn.Linear(feature, feature), nn.BatchNorm1d(feature), nn.PReLU(),
            nn.Linear(feature, 2 * latent),
        )

    def forward(self, lmp: torch.Tensor):
        _, (hidden, _) = self.lstm(lmp)
        return self.head(hidden[-1]).chunk(2, dim=-1)


def time_counter(batch: int, frames: int) -> torch.Tensor:
    """Return ``t/T`` for ``t = 1..T`` as ``(batch, T, 1)``."""
    return (torch.arange(1, frames + 1, dtype=torch.float32) / frames).expand(batch, frames)[..., None]


class TrajectoryGenerator(nn.Module):
    """``Gr(c, z, r_e)``: root velocities ``(B, T, D)`` of a condition and an end location."""

    def __init__(self, condition: int, dims: int, hidden: int, layers: int, exact_end: bool = False):
        super().__init__()
        self.exact_end = exact_end
        self.embed = nn.Sequential(nn.Linear(condition + dims + 1, hidden), nn.PReLU(),
                                   nn.Linear(hidden, hidden))
        self.lstm = nn.LSTM(hidden, hidden, layers, batch_first=True)
        self.head = nn.Sequential(
            nn.Linear(hidden, hidden), nn.PReLU(), nn.Linear(hidden, hidden), nn.PReLU(),
            nn.Linear(hidden, hidden), nn.PReLU(), nn.Linear(hidden, dims),
        )

    def forward(self, condition: torch.Tensor, end: torch.Tensor, frames: int) -> torch.Tensor:
        static = torch.cat([condition, end], dim=-1)[:, None].expand(-1, frames, -1)
        steps = torch.cat([static, time_counter(len(condition), frames)], dim=-1)
        out, _ = self.lstm(self.embed(steps))
        velocity = self.head(out)
        if not self.exact_end:
            return velocity
        # Spread the miss evenly over the steps, so the path ends exactly at ``end``.
        return velocity + (end - velocity.sum(dim=1))[:, None] / frames


class MotionGenerator(nn.Module):
    """Trajectory encoder whose state starts an autoregressive pose decoder."""

    def __init__(self, pose: int, condition: int, dims: int, hidden: int, layers: int,
                 about_path: bool = False):
        super().__init__()
        self.about_path = about_path
        self.trajectory_embed = nn.Sequential(nn.Linear(dims, hidden), nn.PReLU())
        self.trajectory_lstm = nn.LSTM(hidden, hidden, layers, batch_first=True)
        self.embed = nn.Sequential(nn.Linear(pose + condition + 1, hidden), nn.PReLU())
        self.lstm = nn.LSTM(hidden, hidden, layers, batch_first=True)
        self.out = nn.Linear(hidden, pose)

    def forward(self, trajectory: torch.Tensor, condition: torch.Tensor,
                target: torch.Tensor | None = None, teacher: torch.Tensor | None = None):
        """Return poses ``(B, T, F)``; where ``teacher[b, t]``, step ``t+1`` is fed ``target[b, t]``."""
        batch, frames = trajectory.shape[:2]
        _, state = self.trajectory_lstm(self.trajectory_embed(trajectory))
        counter = time_counter(batch, frames)
        joints = self.out.out_features // trajectory.shape[-1]
        previous = trajectory.new_zeros(batch, self.out.out_features)
        outputs = []
        for t in range(frames):
            step = self.embed(torch.cat([previous, condition, counter[:, t]], dim=-1))
            hidden, state = self.lstm(step[:, None], state)
            pose = self.out(hidden[:, 0])
            if self.about_path:  # poses about the guide path (a skip connection): r̂_t + offsets
                pose = pose + trajectory[:, t].repeat(1, joints)
            outputs.append(pose)
            previous = pose if teacher is None else torch.where(teacher[:, t, None], target[:, t], pose)
        return torch.stack(outputs, dim=1)
