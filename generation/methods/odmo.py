"""ODMO, on-demand motion generation (seed 001): mode-aware codes, trajectory first, then motion.

A clip (shifted so that its first root position is the origin, supplement 4) splits
into its root trajectory ``r_t`` and local movement profile ``p_t = m_t - r_t``:

- the LMP encoder (LSTM 64, then FC 256 + BN + PReLU twice, then FC) maps the LMP to
  ``(μ, log σ²)`` of a code ``z`` in ``R^20``;
- the trajectory generator ``Gr(c, z, r_e)`` reads ``flatten(c zᵀ) ++ r_e`` and predicts
  root velocities (two FC with PReLU between, LSTM 2×128, three FC + PReLU, FC);
  ``r̂`` is their cumulative sum from ``r̂_0 = 0``;
- the motion generator encodes ``r̂`` (FC + PReLU, LSTM 2×128) into the initial state of
  an autoregressive decoder (FC + PReLU, LSTM 2×128, FC) fed ``[m̃_{t-1}, c zᵀ, t/T]``
  (networks in :mod:`generation.methods.odmo_networks`).

Loss (Eq. 1-5), per pair of clips, all weights 1: ``L_es`` (same class ``‖μ1-μ2‖²``,
else ``max(0, α-‖μ1-μ2‖)²``, plus ``-ln det Σ + Tr Σ / σ²`` of both) and, for both
clips, ``L_r + L_mre + L_cons`` summed over frames and coordinates.

Sampling (Sec. 3.3): after training, the codes ``μ`` of the real clips get one
Gaussian mixture per action (``odmo``: K by silhouette, small components dropped, see
:mod:`generation.methods.odmo_modes`; ``odmo_conv``: one Gaussian); a code is drawn
from it and ``r_e`` is the end of the real clip whose code is nearest. Options:

- ``mode=k``: draw from mode ``k`` only (numbered by size, 0 the largest; :meth:`ODMO.modes`);
- ``interpolate=(k1, k2)``: an action's n motions walk linearly in code space from a
  draw of mode ``k1`` to one of ``k2``, both made with the noise of its first motion, so
  they equal the first motion of ``mode=k1`` and of ``mode=k2`` with the same seed;
- ``end``: the root's displacement at the last frame from the start point (the training
  clips' mean first root position, where every sample starts: ``r̂_0 = 0``), in the
  data's units. 3D takes three coordinates, or the two horizontal ones (the axes other
  than the skeleton's up axis, in order; the height is the nearest real clip's). One
  point, or one row per motion. :meth:`ODMO.end_distance` gives ``dist_e``.

Two additions, not in the paper, make customisation work without the paper's long
training (with the paper's architecture alone, a few hundred iterations learn to ignore
``r_e``); both are options, off in the ``paper`` preset and on in ``demo`` and ``tiny``:

- ``exact_end``: ``Gr`` spreads its miss ``r_e - Σ v̂`` evenly over its velocities, so
  ``r̂`` ends exactly at ``r_e`` (``L_r`` compares these velocities);
- ``pose_about_path``: the decoder predicts each pose about ``r̂_t`` (a skip
  connection), so the root follows the path unless the decoder learns otherwise.

With both on, trajectory customisation and a small ``dist_e`` hold by construction
rather than by learning; results of such a model say nothing about the paper's
``dist_e``. Checkpoints saved before the options existed had both on and load so.

Mode homogeneity (Sec. 4.3.1) is a property of the latent space measured on real clips:
:meth:`ODMO.clip_modes` puts each real clip in the mode of its action whose Gaussian
explains its code ``μ`` best, and the evaluation compares the APD of the real clips of an
action with their APD within those modes.

Where paper and code leave room: the up axis weighs ``up_weight = 5`` in ``L_mre`` and
``L_r`` ([code], HumanAct12); teacher forcing is drawn per clip and frame at a rate
falling linearly from 1 to 0.3 over ``teacher_forcing_iters``; pairs are formed within
a batch (a partner of the same class with probability ½, else of another); ``Gr`` gets
``t/T`` at every step instead of [code]'s fixed-length expansion, so any length can be
drawn; 2D positions are divided by the data's pixels per metre (:func:`loss_unit`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Sequence

import numpy as np
import torch

from generation.methods.base import Method, MethodConfig, MethodError, register_method
from generation.methods.common import loss_unit, one_hot
from generation.methods.kinematics import clip_bone_lengths
from generation.methods.odmo_modes import (
    discover_modes, gaussian_draws, log_gaussian, nearest, single_gaussian,
)
from generation.methods.odmo_networks import LMPEncoder, MotionGenerator, TrajectoryGenerator
from motion.motion import Motion
from motion.skeletons import get_skeleton

# Codes of the real clips are computed this many clips at a time.
_ENCODE_CHUNK = 512


@dataclass
class ODMOConfig(MethodConfig):
    """ODMO hyper-parameters (Sec. 3.2, supplement 2.1-2.2, Table S2); [code]: from the authors' code."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "demo": {"batch_size": 32, "hidden": 64, "feature": 128, "encoder_hidden": 32,
                 "teacher_forcing_iters": 1000, "min_mode_size": 5, "exact_end": True,
                 "pose_about_path": True},
        "tiny": {"batch_size": 8, "hidden": 16, "feature": 16, "encoder_hidden": 8, "latent": 4,
                 "teacher_forcing_iters": 10, "min_mode_size": 2, "gmm_restarts": 1,
                 "exact_end": True, "pose_about_path": True},
    }

    batch_size: int = 512  # [code], HumanAct12; each clip anchors one pair
    latent: int = 20  # D
    encoder_hidden: int = 64  # LMP encoder LSTM
    feature: int = 256  # LMP encoder FC layers
    hidden: int = 128  # LSTMs and FC layers of both generators
    layers: int = 2
    lr: float = 1e-3
    margin: float = 5.0  # α
    prior_variance: float = 0.05  # σ²
    same_class: float = 0.5  # share of pairs of one class
    up_weight: float = 5.0  # [code] weight of the vertical coordinate in L_mre and L_r
    clip_norm: float = 1.0  # [code]
    teacher_forcing_start: float = 1.0
    teacher_forcing_end: float = 0.3
    teacher_forcing_iters: int = 8000  # [code]: 4000 epochs of about 2 batches
    k_min: int = 3
    k_max: int = 11
    silhouette_ratio: float = 0.95
    min_mode_size: int = 10
    gmm_restarts: int = 5  # [code]
    gmm_reg: float = 1e-6  # added to covariance diagonals
    exact_end: bool = False  # not in the paper: the path is made to end exactly at r_e
    pose_about_path: bool = False  # not in the paper: poses are predicted about r̂_t

    def validate(self) -> None:
        super().validate()
        name = type(self).__name__
        if self.batch_size < 2:
            raise ValueError(f"{name}.batch_size must be at least 2 (batch normalisation, pairs)")
        if min(self.latent, self.encoder_hidden, self.feature, self.hidden, self.layers) < 1:
            raise ValueError(f"{name} sizes (latent, encoder_hidden, feature, hidden, layers) "
                             f"must be >= 1")
        for field in ("same_class", "teacher_forcing_start", "teacher_forcing_end"):
            if getattr(self, field) > 1:
                raise ValueError(f"{name}.{field} must be in [0, 1]; got {getattr(self, field)}")
        if self.prior_variance <= 0:
            raise ValueError(f"{name}.prior_variance must be positive")
        for field in ("exact_end", "pose_about_path"):
            if not isinstance(getattr(self, field), bool):
                raise ValueError(f"{name}.{field} must be true or false; got {getattr(self, field)!r}")
        if not 2 <= self.k_min <= self.k_max:
            raise ValueError(f"{name} needs 2 <= k_min <= k_max; got {self.k_min}, {self.k_max}")


@register_method("odmo")
class ODMO(Method):
    """ODMO: contrastive LMP codes, trajectory then motion; mode-aware sampling (GMM per action)."""

    Config = ODMOConfig
    # Version 2 made exact_end and pose_about_path options; version 1 always had both.
    version = 2
    # One call sees every motion of a request, as interpolation spreads codes over them.
    sample_chunk: ClassVar[int] = 1 << 20
    # odmo_conv: one Gaussian per action instead of the discovered modes.
    one_gaussian: ClassVar[bool] = False

    def build(self):
        skeleton = get_skeleton(self.skeleton)
        cfg = self.config
        self.dims = skeleton.dims
        root = skeleton.root * skeleton.dims
        self.root_slice = slice(root, root + skeleton.dims)
        weights = torch.ones(skeleton.n_joints, skeleton.dims)
        weights[:, skeleton.up_index] = cfg.up_weight
        self.pose_weights = weights.flatten()
        self.root_weights = weights[0]
        condition = len(self.actions) * cfg.latent
        return {
            "encoder": LMPEncoder(self.pose_width - skeleton.dims, cfg.encoder_hidden, cfg.feature,
                                  cfg.latent),
            "trajectory": TrajectoryGenerator(condition, skeleton.dims, cfg.hidden, cfg.layers,
                                              exact_end=cfg.exact_end),
            "motion": MotionGenerator(self.pose_width, condition, skeleton.dims, cfg.hidden, cfg.layers,
                                      about_path=cfg.pose_about_path),
        }

    @classmethod
    def upgrade_checkpoint(cls, checkpoint, version, path):
        """Read version 1 checkpoints: the same networks, with both additions always on."""
        if version != 1:
            return super().upgrade_checkpoint(checkpoint, version, path)
        config = dict(checkpoint["config"])
        config.setdefault("exact_end", True)
        config.setdefault("pose_about_path", True)
        return {**checkpoint, "config": config}

    def build_optimizers(self):
        params = [p for net in self.networks.values() for p in net.parameters()]
        return {"adam": torch.optim.Adam(params, lr=self.config.lr)}

    def prepare(self, clips):
        skeleton = get_skeleton(self.skeleton)
        joints = self.clip_array(clips)
        lengths = np.median(clip_bone_lengths(skeleton, joints), axis=0)
        return {
            "unit": loss_unit(skeleton, lengths),
            "origin": joints[:, 0, skeleton.root].mean(axis=0),
        }

    def encode(self, clips):
        skeleton = get_skeleton(self.skeleton)
        joints = self.clip_array(clips)
        relative = (joints - joints[:, :1, skeleton.root, None]) / float(self.extras["unit"])
        trajectory = relative[:, :, skeleton.root]
        lmp = np.delete(relative - trajectory[:, :, None], skeleton.root, axis=2)
        size = relative.shape[:2]
        return {
            "pose": torch.from_numpy(relative.reshape(size + (-1,))).float(),
            "lmp": torch.from_numpy(lmp.reshape(size + (-1,))).float(),
            "trajectory": torch.from_numpy(trajectory).float(),
            "label": self.action_indices([clip.action for clip in clips]),
        }

    def condition(self, labels: torch.Tensor, codes: torch.Tensor) -> torch.Tensor:
        """Return ``flatten(c zᵀ)`` ``(B, C·D)`` of labels ``(B,)`` and codes ``(B, D)``."""
        classes = one_hot(labels, len(self.actions))
        return (classes[:, :, None] * codes[:, None, :]).flatten(1)

    def teacher_forcing(self) -> float:
        """Return the teacher forcing rate of the current iteration (linear decay)."""
        cfg = self.config
        start, end, iters = cfg.teacher_forcing_start, cfg.teacher_forcing_end, cfg.teacher_forcing_iters
        return start + (end - start) * (min(self.iteration / iters, 1.0) if iters else 1.0)

    def partners(self, labels: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Return a partner index per clip: of its class with probability ``same_class``, else not."""
        size = len(labels)
        same = labels[:, None] == labels[None, :]
        other = ~torch.eye(size, dtype=torch.bool)
        want_same = torch.rand(size, generator=generator) < self.config.same_class
        allowed = torch.where(want_same[:, None], same & other, ~same)
        empty = ~allowed.any(dim=1)
        allowed[empty] = other[empty] if size > 1 else True
        scores = torch.rand(size, size, generator=generator).masked_fill(~allowed, -1.0)
        return scores.argmax(dim=1)

    def train_step(self, batch, generator):
        cfg = self.config
        nets = self.networks
        pose, trajectory, labels = batch["pose"], batch["trajectory"], batch["label"]
        size, frames = pose.shape[:2]
        mu, logvar = nets["encoder"](batch["lmp"])
        codes = mu + torch.exp(0.5 * logvar) * torch.randn(mu.shape, generator=generator)
        condition = self.condition(labels, codes)
        velocity = nets["trajectory"](condition, trajectory[:, -1], frames)
        predicted = velocity.cumsum(dim=1)
        teacher = torch.rand(size, frames, generator=generator) < self.teacher_forcing()
        motion = nets["motion"](predicted, condition, pose, teacher)

        real_velocity = torch.diff(trajectory, dim=1, prepend=torch.zeros_like(trajectory[:, :1]))
        l_r = (self.root_weights * (velocity - real_velocity) ** 2).sum(dim=(1, 2))
        l_mre = (self.pose_weights * (motion - pose) ** 2).sum(dim=(1, 2))
        l_cons = ((predicted - motion[..., self.root_slice]) ** 2).sum(dim=(1, 2))
        partner = self.partners(labels, generator)
        distance2 = ((mu - mu[partner]) ** 2).sum(dim=1)
        contrast = torch.where(labels == labels[partner], distance2,
                               torch.relu(cfg.margin - torch.sqrt(distance2 + 1e-9)) ** 2)
        prior = (-logvar + logvar.exp() / cfg.prior_variance).sum(dim=1)
        per_clip = l_r + l_mre + l_cons + prior
        loss = (contrast + per_clip + per_clip[partner]).mean()

        optimizer = self.optimizers["adam"]
        optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_([p for net in self.networks.values() for p in net.parameters()],
                                       cfg.clip_norm)
        optimizer.step()
        return {"es": (contrast + prior + prior[partner]).mean().item(), "r": l_r.mean().item(),
                "mre": l_mre.mean().item(), "cons": l_cons.mean().item()}

    # Modes, fitted after training.

    def fit(self, clips: Sequence[Motion], iters: int, seed: int = 0, progress: bool = True,
            save_to=None, save_every: int = 0) -> dict[str, float]:
        """Train as :meth:`Method.fit`, then fit the per-action code distributions to ``clips``."""
        losses = super().fit(clips, iters, seed=seed, progress=progress, save_to=save_to,
                             save_every=save_every)
        self.extras.update(self.fit_modes(clips))
        return losses

    @torch.no_grad()
    def fit_modes(self, clips: Sequence[Motion]) -> dict:
        """Return the codes, end locations and modes (or Gaussian) of each action's clips."""
        cfg = self.config
        data = self.encode(list(clips))
        encoder = self.networks["encoder"].eval()
        codes = torch.cat([encoder(data["lmp"][i:i + _ENCODE_CHUNK])[0]
                           for i in range(0, len(clips), _ENCODE_CHUNK)]).double().numpy()
        ends = data["trajectory"][:, -1].double().numpy()
        labels = data["label"].numpy()
        out = {"codes": {}, "ends": {}, "modes": {}}
        for index, action in enumerate(self.actions):
            mine = labels == index
            if not mine.any():
                continue
            out["codes"][action], out["ends"][action] = codes[mine], ends[mine]
            if self.one_gaussian:
                out["modes"][action] = single_gaussian(codes[mine], cfg.gmm_reg)
            else:
                rng = np.random.default_rng([self.seed or 0, index])
                out["modes"][action] = discover_modes(
                    codes[mine], rng, cfg.k_min, cfg.k_max, cfg.silhouette_ratio,
                    cfg.min_mode_size, cfg.gmm_restarts, cfg.gmm_reg)
        return out

    @torch.no_grad()
    def clip_modes(self, clips: Sequence[Motion]) -> np.ndarray:
        """Return the mode ``(N,)`` of each real clip: of its action, the likeliest for its code ``μ``.

        These group real clips for mode homogeneity (Sec. 4.3.1: "the set of real motion
        sequences belonging to mode k inside category c").
        """
        clips = self._check_clips(list(clips), kind="real clip to find the mode of")
        data = self.encode(clips)
        encoder = self.networks["encoder"].eval()
        codes = torch.cat([encoder(data["lmp"][i:i + _ENCODE_CHUNK])[0]
                           for i in range(0, len(clips), _ENCODE_CHUNK)]).double().numpy()
        fitted = self._fitted_modes()
        missing = sorted({self.actions[i] for i in data["label"].unique().tolist()} - set(fitted))
        if missing:
            raise MethodError(f"{self.name} has no modes of action {', '.join(missing)}: its "
                              f"training clips had none")
        return self._likeliest_modes(data["label"], codes)

    def modes(self) -> dict[str, list[dict]]:
        """Return each action's modes: ``{"mode": k, "size": clips, "weight": share}``, largest first."""
        fitted = self._fitted_modes()
        return {
            action: [{"mode": k, "size": int(size), "weight": float(weight)} for k, (size, weight)
                     in enumerate(zip(fitted[action]["sizes"], fitted[action]["weights"]))]
            if action in fitted else []
            for action in self.actions
        }

    def _fitted_modes(self) -> dict:
        if "modes" not in self.extras:
            raise MethodError(
                f"this {self.name} checkpoint has no fitted modes (its training was interrupted "
                f"before the end); resume training to fit them"
            )
        return self.extras["modes"]

    # Sampling.

    def latent_codes(self, actions: Sequence[str], seed: int = 0, mode: int | None = None,
                     interpolate: tuple[int, int] | None = None) -> np.ndarray:
        """Return the codes ``(N, D)`` that :meth:`sample` with these arguments decodes."""
        labels = self.action_indices(actions)
        return self._draw_codes(labels, torch.Generator().manual_seed(int(seed)), mode, interpolate)

    def _draw_codes(self, labels, generator, mode=None, interpolate=None) -> np.ndarray:
        fitted = self._fitted_modes()
        if interpolate is not None and (mode is not None or len(interpolate) != 2):
            raise MethodError("interpolate takes two modes (k1, k2), and no mode option with it")
        # numpy fills arrays row by row, so a motion's draws do not depend on how many follow.
        rng = np.random.default_rng(int(torch.randint(2**62, (1,), generator=generator)))
        noise = rng.standard_normal((len(labels), self.config.latent))
        pick = rng.random(len(labels))
        codes = np.empty_like(noise)
        for index in labels.unique().tolist():
            rows = np.flatnonzero((labels == index).numpy())
            mixture = self._mixture(self.actions[index], fitted, [mode, *(interpolate or ())])
            if interpolate is not None:
                first, last = (gaussian_draws(mixture["means"][[k]], mixture["covariances"][[k]],
                                              noise[rows[:1]]) for k in interpolate)
                alpha = np.linspace(0.0, 1.0, len(rows))[:, None]
                codes[rows] = (1 - alpha) * first + alpha * last
                continue
            if mode is None:
                cumulative = np.cumsum(mixture["weights"])
                chosen = np.searchsorted(cumulative, pick[rows] * cumulative[-1], side="right")
                chosen = np.minimum(chosen, len(cumulative) - 1)
            else:
                chosen = np.full(len(rows), mode)
            codes[rows] = gaussian_draws(mixture["means"][chosen], mixture["covariances"][chosen],
                                         noise[rows])
        return codes

    def _mixture(self, action: str, fitted: dict, wanted: list) -> dict:
        """Return the fitted modes of ``action``, checking that the ``wanted`` ones exist."""
        if action not in fitted:
            raise MethodError(
                f"{self.name} has no codes of action {action!r}: its training clips had none; "
                f"sample one of {', '.join(fitted)}"
            )
        count = len(fitted[action]["weights"])
        for k in wanted:
            if k is not None and (isinstance(k, bool) or int(k) != k or not 0 <= k < count):
                raise MethodError(
                    f"action {action!r} has {count} mode(s), 0..{count - 1} (see --list-modes); "
                    f"got mode {k!r}"
                )
        return fitted[action]

    def _nearest_ends(self, labels: torch.Tensor, codes: np.ndarray) -> np.ndarray:
        """Return the end location (in model units) of the real clip nearest each code."""
        ends = np.zeros((len(labels), self.dims))
        for index in labels.unique().tolist():
            rows = (labels == index).numpy()
            action = self.actions[index]
            found = nearest(codes[rows], self.extras["codes"][action])
            ends[rows] = self.extras["ends"][action][found]
        return ends

    def end_axes(self, end) -> tuple[np.ndarray, list[int]]:
        """Return ``end`` as rows ``(1 or N, k)`` and the coordinate axes its ``k`` columns give."""
        up = get_skeleton(self.skeleton).up_index
        end = np.atleast_2d(np.asarray(end, dtype=np.float64))
        horizontal = [axis for axis in range(self.dims) if axis != up]
        if end.ndim != 2 or end.shape[1] not in {self.dims, len(horizontal) if self.dims == 3 else 0}:
            axes = "".join("xyz"[a] for a in horizontal)
            either = f" (or the 2 horizontal ones, {axes})" * (self.dims == 3)
            raise MethodError(f"end must give {self.dims} coordinates{either}, once or once per motion; "
                              f"got shape {np.shape(end)}")
        if not np.isfinite(end).all():
            raise MethodError(f"end must be finite; got {end.tolist()}")
        return end, list(range(self.dims)) if end.shape[1] == self.dims else horizontal

    def end_distance(self, motions, end) -> np.ndarray:
        """Return ``dist_e`` per motion: squared distance of its final root from the target ``end``.

        ``motions`` are :class:`Motion` objects or joints ``(N, T, J, D)``; ``end`` is as in
        sampling (displacement from the start point, only the coordinates given count).
        """
        skeleton = get_skeleton(self.skeleton)
        joints = np.stack([m.joints if isinstance(m, Motion) else m for m in motions]).astype(np.float64)
        end, axes = self.end_axes(end)
        final = joints[:, -1, skeleton.root] - np.asarray(self.extras["origin"], dtype=np.float64)
        return ((final[:, axes] - end) ** 2).sum(axis=1)

    def sample(self, actions: Sequence[str], frames: int | None = None, seed: int = 0,
               **options) -> list[Motion]:
        """Sample as :meth:`Method.sample`; each motion's ``meta`` also names its ``mode`` and ``end``.

        ``mode`` is the mode asked for, else the mode whose Gaussian explains the drawn code
        best (none for interpolations); ``end`` ``(D,)``, only when ``end`` is given, is the
        target the trajectory was made to reach: the given coordinates, and for the others
        the nearest real clip's. Metric files carry both (``modes``, ``end_targets``).
        """
        motions = super().sample(actions, frames, seed, **options)
        if not motions:
            return motions
        labels = self.action_indices(actions)
        mode, interpolate, end = options.get("mode"), options.get("interpolate"), options.get("end")
        codes = self.latent_codes(actions, seed, mode, interpolate)
        if interpolate is None:
            if mode is None:
                modes = self._likeliest_modes(labels, codes)
            else:
                modes = np.full(len(labels), int(mode))
            for motion, k in zip(motions, modes):
                motion.meta["mode"] = int(k)
        if end is not None:
            target, axes = self.end_axes(end)
            targets = self._nearest_ends(labels, codes) * float(self.extras["unit"])
            targets[:, axes] = target
            for motion, row in zip(motions, targets):
                motion.meta["end"] = row
        return motions

    def _likeliest_modes(self, labels: torch.Tensor, codes: np.ndarray) -> np.ndarray:
        """Return, per code, the mode of its action whose weighted Gaussian gives it most density."""
        fitted = self._fitted_modes()
        modes = np.zeros(len(labels), dtype=np.int64)
        for index in labels.unique().tolist():
            rows = (labels == index).numpy()
            mixture = fitted[self.actions[index]]
            scores = log_gaussian(codes[rows], mixture["means"], mixture["covariances"])
            modes[rows] = (scores + np.log(mixture["weights"])).argmax(axis=1)
        return modes

    def generate(self, labels, frames, generator, mode=None, interpolate=None, end=None):
        """Sample; ``mode``, ``interpolate`` and ``end`` as in the module documentation."""
        if interpolate is not None:
            interpolate = tuple(interpolate)
        codes = self._draw_codes(labels, generator, mode, interpolate)
        ends = self._nearest_ends(labels, codes)
        unit = float(self.extras["unit"])
        if end is not None:
            target, axes = self.end_axes(end)
            if len(target) not in (1, len(labels)):
                raise MethodError(f"end has {len(target)} rows for {len(labels)} motions; "
                                  f"give 1 or {len(labels)}")
            ends[:, axes] = target / unit
        condition = self.condition(labels, torch.from_numpy(codes).float())
        velocity = self.networks["trajectory"](condition, torch.from_numpy(ends).float(), frames)
        motion = self.networks["motion"](velocity.cumsum(dim=1), condition)
        skeleton = get_skeleton(self.skeleton)
        joints = motion.double().numpy().reshape(len(labels), frames, skeleton.n_joints, self.dims)
        return (joints * unit + np.asarray(self.extras["origin"], dtype=np.float64)).astype(np.float32)


@register_method("odmo_conv")
class ODMOConv(ODMO):
    """ODMO_conv: the same model, sampled from one Gaussian per action (not mode-aware)."""

    one_gaussian = True
