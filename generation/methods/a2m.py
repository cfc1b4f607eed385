"""Action2Motion (seed 000): a conditional temporal VAE on Lie-algebra poses with forward kinematics.

Per frame ``t`` (Sec. 3.2.2, Eq. 7-8, Table 3), with ``c_t = t/T`` and ``a`` one-hot:

- posterior ``GRU_φ(E(p_t, a, c_t)) -> (μ_φ, log σ²_φ)``, ``z_t ~ N(μ_φ, σ_φ)``;
- prior ``GRU_ψ(E(p_{t-1}, a, c_t)) -> (μ_ψ, log σ²_ψ)``;
- generator ``E(p_{t-1}, a, c_t, z_t) -> 2-layer GRU_θ -> D_e -> (root, Lie params)``,
  the Lie part through ``π·tanh(Linear(tanh(·)))`` as in the authors' code;
- forward kinematics turns (root, Lie params, bone lengths) into joints.

Loss (Eq. 9): per frame the mean squared error between generated and real joints plus
``λ KL(q_φ || p_ψ)``, summed over frames. While training, FK uses each clip's own bone
lengths (as the authors' code does), so the loss compares like with like; samples
use the training set's median bone lengths, or any given ones (Fig. 6).

Choices where paper and code leave room, all documented here:

- the pose vector ``p_t`` fed to the networks is the generator's own output space:
  normalised root position and Lie parameters. Real poses get theirs by inverse
  kinematics; at test time the previous output is fed back as is (``p_0 = 0``, the
  rest pose at the mean root position). Keeping the dynamics in Lie space makes a
  motion independent of the bone lengths it is drawn with;
- teacher forcing ``V ~ Bernoulli(0.6)`` is drawn per sequence (the paper: "for the
  entire sequence"), and ``V = 1`` feeds real poses (the authors' code has it reversed);
- the root is predicted relative to the clip's first root position on the floor: its
  horizontal start is subtracted (its height kept, so bodies stay on the floor;
  in 2D the image row is kept). Samples start at the training clips' mean start;
- 2D skeletons have no so(3): a bone gets an in-plane angle and an out-of-plane tilt
  (see :mod:`generation.methods.kinematics`); their projected bone lengths are
  ``b cos φ``, not constant, as in real projected data;
- 2D losses are taken in metre-like units (pixels divided by the mean bone length over
  0.25 m) so that λ keeps its meaning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
from torch import nn

from generation.methods.base import Method, MethodConfig, MethodError, register_method
from generation.methods.common import (
    gaussian_kl,
    horizontal_start,
    loss_unit,
    mean_std,
    one_hot,
    relative_to_start,
)
from generation.methods.kinematics import Kinematics, clip_bone_lengths, rest_directions
from motion.skeletons import get_skeleton

# Inverse kinematics runs in float64 over this many clips at a time.
_IK_CHUNK = 256
# Rest directions are estimated from at most this many frames.
_REST_FRAMES = 50_000


@dataclass
class A2MConfig(MethodConfig):
    """Action2Motion hyper-parameters (A.2, Table 3); defaults as for HumanAct12."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        # Small enough to train in about a minute on a laptop CPU (``make demo``).
        "demo": {"hidden": 64, "embed": 64, "latent": 16, "batch_size": 32, "lr": 1e-3},
        "tiny": {"hidden": 16, "embed": 16, "latent": 4, "batch_size": 8},
    }

    batch_size: int = 128
    hidden: int = 128  # GRU units of prior, posterior and generator
    embed: int = 128  # output size of every encoder E
    latent: int = 30  # size of z_t
    generator_layers: int = 2
    lr: float = 2e-4
    weight_decay: float = 1e-5
    kl_weight: float = 0.01  # λ: 0.01 for HumanAct12, 0.1 for NTU-RGB-D and CMU MoCap
    teacher_forcing: float = 0.6  # p_tf
    rotation_frames: str = "chain"  # "chain": Eq. 4; "tree": branches continue their parent bone
    time_counter: str = "paper"  # "paper": c_t = t/T for t = 1..T; "code": (t-1)/(T-1)

    def validate(self) -> None:
        super().validate()
        if not 0.0 <= self.teacher_forcing <= 1.0:
            raise ValueError(f"A2MConfig.teacher_forcing must be in [0, 1]; got {self.teacher_forcing}")
        if self.rotation_frames not in ("chain", "tree"):
            raise ValueError(
                f"A2MConfig.rotation_frames must be 'chain' or 'tree'; got {self.rotation_frames!r}"
            )
        if self.time_counter not in ("paper", "code"):
            raise ValueError(
                f"A2MConfig.time_counter must be 'paper' or 'code'; got {self.time_counter!r}"
            )
        if min(self.hidden, self.embed, self.latent, self.generator_layers) < 1:
            raise ValueError("A2MConfig sizes (hidden, embed, latent, generator_layers) must be >= 1")


class GaussianGRU(nn.Module):
    """Encoder, one GRU cell, and linear heads for μ and log σ²: A2M's prior and posterior."""

    def __init__(self, inputs: int, embed: int, hidden: int, latent: int):
        super().__init__()
        self.encoder = nn.Linear(inputs, embed)
        self.gru = nn.ModuleList([nn.GRUCell(embed, hidden)])
        self.mu_net = nn.Linear(hidden, latent)
        self.logvar_net = nn.Linear(hidden, latent)

    def forward(self, x: torch.Tensor, state: list[torch.Tensor]):
        hidden = self.gru[0](self.encoder(x), state[0])
        return self.mu_net(hidden), self.logvar_net(hidden), [hidden]


class GRUGenerator(nn.Module):
    """Encoder, stacked GRU cells, linear decoder ``D_e``: the generator ``GRU_θ``."""

    def __init__(self, inputs: int, embed: int, hidden: int, layers: int, outputs: int):
        super().__init__()
        self.encoder = nn.Linear(inputs, embed)
        self.gru = nn.ModuleList(
            [nn.GRUCell(embed if i == 0 else hidden, hidden) for i in range(layers)]
        )
        self.decoder = nn.Linear(hidden, outputs)

    def forward(self, x: torch.Tensor, state: list[torch.Tensor]):
        hidden = self.encoder(x)
        new_state = []
        for cell, previous in zip(self.gru, state):
            hidden = cell(hidden, previous)
            new_state.append(hidden)
        return self.decoder(hidden), new_state


class LieGenerator(GRUGenerator):
    """The generator with ``D_e`` to (root, Lie parameters), the Lie part through ``π·tanh``."""

    def __init__(self, inputs: int, embed: int, hidden: int, layers: int, root: int, params: int):
        super().__init__(inputs, embed, hidden, layers, root + params)
        self.root = root
        self.lie_output = nn.Linear(params, params)

    def forward(self, x: torch.Tensor, state: list[torch.Tensor]):
        out, new_state = super().forward(x, state)
        lie = math.pi * torch.tanh(self.lie_output(torch.tanh(out[:, self.root:])))
        return torch.cat([out[:, : self.root], lie], dim=-1), new_state


@register_method("a2m")
class A2M(Method):
    """Action2Motion: conditional temporal VAE, Lie algebra pose, forward kinematics."""

    Config = A2MConfig

    def build(self):
        skeleton = get_skeleton(self.skeleton)
        self.root_size = skeleton.dims
        self.param_size = 3 if skeleton.dims == 3 else 2
        self.n_params = (skeleton.n_joints - 1) * self.param_size
        self.pose_size = self.root_size + self.n_params
        self._kinematics = None
        return self._vae_networks()

    def _vae_networks(self) -> dict[str, nn.Module]:
        """Return posterior, prior and generator over pose vectors ``p_t`` of ``pose_size``."""
        cfg = self.config
        inputs = self.pose_size + len(self.actions) + 1  # p_t or p_{t-1}, a, c_t
        return {
            "posterior": GaussianGRU(inputs, cfg.embed, cfg.hidden, cfg.latent),
            "prior": GaussianGRU(inputs, cfg.embed, cfg.hidden, cfg.latent),
            "generator": self._generator(inputs + cfg.latent),
        }

    def _generator(self, inputs: int) -> nn.Module:
        """Return the generator ``GRU_θ`` of ``inputs`` ``(p_{t-1}, a, c_t, z_t)``."""
        cfg = self.config
        return LieGenerator(inputs, cfg.embed, cfg.hidden, cfg.generator_layers, self.root_size,
                            self.n_params)

    def build_optimizers(self):
        # One Adam over all three networks equals the code's three Adams with equal settings.
        params = [p for net in self.networks.values() for p in net.parameters()]
        return {"adam": torch.optim.Adam(params, lr=self.config.lr,
                                         weight_decay=self.config.weight_decay)}

    @property
    def kinematics(self) -> Kinematics:
        """Return the forward/inverse kinematics with the rest directions of the training data."""
        rest = self.extras["rest"]
        if self._kinematics is None or self._kinematics_rest is not rest:
            self._kinematics = Kinematics(self.skeleton, rest, self.config.rotation_frames)
            self._kinematics_rest = rest
        return self._kinematics

    def prepare(self, clips):
        skeleton = get_skeleton(self.skeleton)
        joints = self.clip_array(clips)
        starts = horizontal_start(skeleton, joints)
        lengths = clip_bone_lengths(skeleton, joints)
        bone_lengths = np.median(lengths, axis=0)
        frames = joints.reshape(-1, skeleton.n_joints, skeleton.dims)
        step = max(1, len(frames) // _REST_FRAMES)
        root = (joints[:, :, skeleton.root] - starts[:, None]).reshape(-1, skeleton.dims)
        root_mean, root_std = mean_std(root, floor=1e-3 * float(bone_lengths.max()))
        return {
            "rest": rest_directions(skeleton, frames[::step]),
            "bone_lengths": bone_lengths,
            "root_mean": root_mean,
            "root_std": root_std,
            "origin": starts.mean(axis=0),
            "unit": loss_unit(skeleton, bone_lengths),
        }

    def encode(self, clips):
        skeleton = get_skeleton(self.skeleton)
        joints = self.clip_array(clips)
        relative = relative_to_start(skeleton, joints)
        lengths = clip_bone_lengths(skeleton, joints)
        poses = []
        for i in range(0, len(clips), _IK_CHUNK):
            chunk = torch.from_numpy(relative[i:i + _IK_CHUNK])
            params, root = self.kinematics.inverse(chunk, torch.from_numpy(lengths[i:i + _IK_CHUNK, None]))
            poses.append(self._pose_vector(params, root))
        labels = self.action_indices([clip.action for clip in clips])
        return {
            "pose": torch.cat(poses).float(),
            "target": torch.from_numpy(relative).float(),
            "lengths": torch.from_numpy(lengths).float(),
            "label": labels,
        }

    def _pose_vector(self, params: torch.Tensor, root: torch.Tensor) -> torch.Tensor:
        mean = torch.as_tensor(self.extras["root_mean"], dtype=root.dtype)
        std = torch.as_tensor(self.extras["root_std"], dtype=root.dtype)
        return torch.cat([(root - mean) / std, params.flatten(-2)], dim=-1)

    def _joints(self, poses: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        """Return joints ``(B, T, J, D)`` of pose vectors ``(B, T, F)`` with lengths ``(B, J)``."""
        mean = torch.as_tensor(self.extras["root_mean"], dtype=poses.dtype)
        std = torch.as_tensor(self.extras["root_std"], dtype=poses.dtype)
        root = poses[..., : self.root_size] * std + mean
        params = poses[..., self.root_size:].unflatten(-1, (-1, self.param_size))
        return self.kinematics.forward(params, root, lengths[:, None, :])

    def _condition(self, classes: torch.Tensor, t: int, frames: int) -> torch.Tensor:
        if self.config.time_counter == "paper":
            counter = (t + 1) / frames
        else:
            counter = t / max(frames - 1, 1)
        return torch.cat([classes, classes.new_full((len(classes), 1), counter)], dim=-1)

    def _initial_state(self, net: nn.Module, batch: int) -> list[torch.Tensor]:
        return [torch.zeros(batch, cell.hidden_size) for cell in net.gru]

    def train_step(self, batch, generator):
        posterior, prior, decoder = (self.networks[k] for k in ("posterior", "prior", "generator"))
        pose, target = batch["pose"], batch["target"]
        size, frames = pose.shape[:2]
        classes = one_hot(batch["label"], len(self.actions))
        teacher = torch.rand(size, 1, generator=generator) < self.config.teacher_forcing
        previous = torch.zeros_like(pose[:, 0])
        states = [self._initial_state(net, size) for net in (posterior, prior, decoder)]
        outputs, kl = [], 0.0
        for t in range(frames):
            condition = self._condition(classes, t, frames)
            mu_q, logvar_q, states[0] = posterior(torch.cat([pose[:, t], condition], -1), states[0])
            mu_p, logvar_p, states[1] = prior(torch.cat([previous, condition], -1), states[1])
            noise = torch.randn(mu_q.shape, generator=generator)
            z = mu_q + torch.exp(0.5 * logvar_q) * noise
            out, states[2] = decoder(torch.cat([previous, condition, z], -1), states[2])
            outputs.append(out)
            kl = kl + gaussian_kl(mu_q, logvar_q, mu_p, logvar_p)
            previous = torch.where(teacher, pose[:, t], out)
        joints = self._joints(torch.stack(outputs, dim=1), batch["lengths"])
        unit = float(self.extras["unit"])
        recon = (((joints - target) / unit) ** 2).mean(dim=(0, 2, 3)).sum()
        loss = recon + self.config.kl_weight * kl
        optimizer = self.optimizers["adam"]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        return {"recon": recon.item() / frames, "kl": kl.item() / frames}

    def generate(self, labels, frames, generator, bone_lengths=None):
        """Sample with the prior; ``bone_lengths`` ``(J,)`` in joint order replaces the data's."""
        lengths = self._bone_lengths(bone_lengths)
        prior, decoder = self.networks["prior"], self.networks["generator"]
        size = len(labels)
        classes = one_hot(labels, len(self.actions))
        previous = torch.zeros(size, self.pose_size)
        prior_state = self._initial_state(prior, size)
        decoder_state = self._initial_state(decoder, size)
        outputs = []
        for t in range(frames):
            condition = self._condition(classes, t, frames)
            mu_p, logvar_p, prior_state = prior(torch.cat([previous, condition], -1), prior_state)
            z = mu_p + torch.exp(0.5 * logvar_p) * torch.randn(mu_p.shape, generator=generator)
            previous, decoder_state = decoder(torch.cat([previous, condition, z], -1), decoder_state)
            outputs.append(previous)
        # Forward kinematics in float64 keeps the bone lengths exact to float32 output precision.
        poses = torch.stack(outputs, dim=1).double()
        joints = self._joints(poses, torch.from_numpy(lengths).expand(size, -1))
        joints = joints + torch.from_numpy(np.asarray(self.extras["origin"], dtype=np.float64))
        return joints.numpy().astype(np.float32)

    def _bone_lengths(self, bone_lengths) -> np.ndarray:
        skeleton = get_skeleton(self.skeleton)
        if bone_lengths is None:
            return np.asarray(self.extras["bone_lengths"], dtype=np.float64)
        lengths = np.asarray(bone_lengths, dtype=np.float64)
        if lengths.shape != (skeleton.n_joints,):
            raise MethodError(
                f"bone_lengths must have shape ({skeleton.n_joints},), one per joint of "
                f"{skeleton.name!r} in joint order (root ignored), as skeleton.bone_lengths(pose) "
                f"gives; got shape {lengths.shape}"
            )
        bones = np.delete(lengths, skeleton.root)
        if not np.isfinite(bones).all() or (bones <= 0).any():
            raise MethodError(f"bone_lengths must be finite and positive (root aside); got {lengths}")
        return lengths
