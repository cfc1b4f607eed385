"""The interface every generative method implements: config, fit, sample, save, load."""

from __future__ import annotations

import inspect
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import ClassVar, Sequence

import numpy as np
import torch
from tqdm import tqdm

from generation.methods.common import to_arrays, to_tensors
from motion.motion import Motion
from motion.registry import Registry
from motion.skeletons import get_skeleton

METHODS = Registry("method", package="generation.methods")
register_method = METHODS.register

CHECKPOINT_FORMAT = 1
CHECKPOINT_KEYS = (
    "format", "method", "config", "skeleton", "actions", "fps", "frames",
    "networks", "optimizers", "iteration", "extras",
)


class MethodError(ValueError):
    """A method was given input it cannot use (unknown action, unfit clips, no training)."""


class CheckpointError(ValueError):
    """A checkpoint is missing, unreadable, or of another method or skeleton."""


@dataclass
class MethodConfig:
    """Hyper-parameters of a method; the defaults are the paper's values.

    Subclasses add fields (all with defaults) and name presets in ``PRESETS``: each
    maps to the fields it changes from the defaults (``"paper"`` changes none).
    """

    PRESETS: ClassVar[dict[str, dict]] = {"paper": {}}

    batch_size: int = 128

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first field whose value cannot work."""
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                if not math.isfinite(value) or value < 0:
                    raise ValueError(
                        f"{type(self).__name__}.{item.name} must be a finite non-negative "
                        f"number; got {value!r}"
                    )
        if self.batch_size < 1:
            raise ValueError(f"{type(self).__name__}.batch_size must be at least 1")

    @classmethod
    def preset(cls, name: str) -> "MethodConfig":
        """Return the config of a named preset (``"paper"``, ``"tiny"``, ...)."""
        if name not in cls.PRESETS:
            raise ValueError(
                f"unknown preset {name!r} for {cls.__name__}; choose one of: "
                f"{', '.join(sorted(cls.PRESETS))}"
            )
        return cls(**cls.PRESETS[name])

    @classmethod
    def from_dict(cls, values: dict) -> "MethodConfig":
        """Return a config from :meth:`to_dict` output; unknown keys are an error."""
        known = {item.name for item in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(
                f"{cls.__name__} has no fields {', '.join(unknown)}; "
                f"its fields are {', '.join(sorted(known))}"
            )
        return cls(**values)

    def to_dict(self) -> dict:
        return asdict(self)


class Method:
    """A generative method of motions; subclasses set ``Config`` and implement the hooks.

    Hooks: :meth:`build` (networks), :meth:`build_optimizers`, :meth:`prepare`
    (statistics of the training clips, kept in ``extras`` and saved),
    :meth:`encode` (clips to training tensors), :meth:`train_step` (one iteration) and
    :meth:`generate` (a batch of joint arrays). The base class does the rest: seeding,
    batching, progress, resuming, checkpoints, validation.
    """

    name: ClassVar[str] = ""  # set by register_method
    Config: ClassVar[type[MethodConfig]] = MethodConfig
    # Motions generated per forward pass; bounds sampling memory.
    sample_chunk: ClassVar[int] = 1024
    # The version of a method's networks, saved in its checkpoints: raise it when a change
    # makes old weights mean something else, and say what changed in ``version_change``.
    # Checkpoints saved before versions were recorded are version 1.
    version: ClassVar[int] = 1
    version_change: ClassVar[str] = ""

    def __init__(self, config: MethodConfig | None, skeleton: str, actions: Sequence[str],
                 fps: float, frames: int):
        config = self.Config() if config is None else config
        if not isinstance(config, self.Config):
            raise MethodError(
                f"{self.name or type(self).__name__} needs a {self.Config.__name__}; "
                f"got a {type(config).__name__}"
            )
        try:
            get_skeleton(skeleton)
        except KeyError as exc:
            raise MethodError(exc.args[0]) from None
        if isinstance(actions, str) or not actions or not all(isinstance(a, str) for a in actions):
            raise MethodError(f"actions must be a non-empty list of action names; got {actions!r}")
        if len(set(actions)) != len(actions):
            raise MethodError(f"actions must be distinct; got {list(actions)}")
        if not fps or not math.isfinite(fps) or fps <= 0:
            raise MethodError(f"fps must be a positive number; got {fps!r}")
        if int(frames) != frames or frames < 2:
            raise MethodError(f"frames must be an integer of at least 2; got {frames!r}")
        self.config = config
        self.skeleton = skeleton
        self.actions = list(actions)
        self.fps = float(fps)
        self.frames = int(frames)
        self.iteration = 0
        self.seed: int | None = None
        self.losses: dict[str, float] = {}
        self.extras: dict = {}
        self._initialise(0)

    def __repr__(self):
        return (
            f"<{self.name} on {self.skeleton}: {len(self.actions)} actions, {self.frames} "
            f"frames at {self.fps:g} fps, {self.iteration} iterations>"
        )

    # Hooks for subclasses.

    def build(self) -> dict[str, torch.nn.Module]:
        """Return the networks by name (called under a seeded RNG)."""
        raise NotImplementedError

    def build_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        """Return the optimizers by name, over ``self.networks``."""
        raise NotImplementedError

    def prepare(self, clips: list[Motion]) -> dict:
        """Return statistics of the training clips needed to train and sample (``extras``)."""
        raise NotImplementedError

    def encode(self, clips: list[Motion]) -> dict[str, torch.Tensor]:
        """Return training tensors whose first axis indexes the clips."""
        raise NotImplementedError

    def train_step(self, batch: dict[str, torch.Tensor], generator: torch.Generator) -> dict[str, float]:
        """Run one optimisation step on a batch; return the losses to show."""
        raise NotImplementedError

    def generate(self, labels: torch.Tensor, frames: int, generator: torch.Generator,
                 **options) -> np.ndarray:
        """Return joints ``(N, frames, J, D)`` float32 for action indices ``(N,)``."""
        raise NotImplementedError

    # The shared machinery.

    def _initialise(self, seed: int) -> None:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.networks = self.build()
        self.optimizers = self.build_optimizers()

    @property
    def n_parameters(self) -> int:
        """Return the number of trainable parameters of all networks."""
        return sum(p.numel() for net in self.networks.values() for p in net.parameters())

    @property
    def pose_width(self) -> int:
        """Return the numbers in one flattened pose, ``J * D`` of the method's skeleton."""
        skeleton = get_skeleton(self.skeleton)
        return skeleton.n_joints * skeleton.dims

    @property
    def trained(self) -> bool:
        return bool(self.extras)

    def action_indices(self, actions: Sequence[str]) -> torch.Tensor:
        """Return the class indices ``(N,)`` of action names; unknown names are an error."""
        if isinstance(actions, str):
            raise MethodError(
                f"actions must be a list with one action name per motion; got the string "
                f"{actions!r} (pass [{actions!r}])"
            )
        index = {action: i for i, action in enumerate(self.actions)}
        unknown = sorted({a for a in actions if a not in index}, key=str)
        if unknown:
            raise MethodError(
                f"{self.name} knows no action {', '.join(map(repr, unknown))}; "
                f"its actions are {', '.join(self.actions)}"
            )
        return torch.tensor([index[a] for a in actions], dtype=torch.long)

    def _check_clips(self, clips: Sequence[Motion], kind: str = "training clip") -> list[Motion]:
        if not clips:
            raise MethodError(f"{self.name} needs at least one {kind}; got none")
        for i, clip in enumerate(clips):
            where = f"{kind} {i} ({clip.action!r}, {clip.meta or 'no provenance'})"
            if clip.skeleton != self.skeleton:
                raise MethodError(
                    f"{where} has skeleton {clip.skeleton!r}, but this {self.name} model is "
                    f"for {self.skeleton!r}; train one model per skeleton"
                )
            if abs(clip.fps - self.fps) > 1e-3 * self.fps:
                raise MethodError(
                    f"{where} is at {clip.fps:g} fps, the model at {self.fps:g} fps; "
                    f"resample the clips (dataset.clips(fps=...)) or build the model for their fps"
                )
            if clip.frames < self.frames:
                raise MethodError(
                    f"{where} has {clip.frames} frames, fewer than the model's {self.frames}; "
                    f"ask the dataset for longer clips (dataset.clips(frames=...))"
                )
            if clip.action not in self.actions:
                raise MethodError(
                    f"{where} has an action the model does not know; its actions are "
                    f"{', '.join(self.actions)}"
                )
            clip.check_finite()
        return list(clips)

    def clip_array(self, clips: Sequence[Motion]) -> np.ndarray:
        """Return the first ``frames`` frames of each clip as ``(N, frames, J, D)`` float64."""
        return np.stack([clip.joints[: self.frames] for clip in clips]).astype(np.float64)

    def fit(self, clips: Sequence[Motion], iters: int, seed: int = 0, progress: bool = True,
            save_to: str | Path | None = None, save_every: int = 0) -> dict[str, float]:
        """Train for ``iters`` more iterations; return the last losses.

        A fresh model is initialised from ``seed`` and takes its statistics from
        ``clips``; a trained or loaded one continues where it stopped (same weights,
        optimizer state and iteration counter). Iteration ``i`` draws its batch and
        noise from a generator seeded by ``(seed, i)``, so training in several calls
        gives the same weights as in one. With ``save_to``, a checkpoint is written every
        ``save_every`` iterations.
        """
        if int(iters) != iters or iters < 0:
            raise MethodError(f"iters must be a non-negative integer; got {iters!r}")
        if int(seed) != seed or seed < 0:
            raise MethodError(f"seed must be a non-negative integer; got {seed!r}")
        clips = self._check_clips(clips)
        if self.iteration == 0:
            self._initialise(int(seed))
            self.extras = self.prepare(clips)
        self.seed = int(seed)
        data = self.encode(clips)
        count = len(clips)
        bar = tqdm(total=int(iters), desc=f"{self.name} {self.skeleton}", unit="it",
                   disable=not progress, dynamic_ncols=True)
        try:
            for _ in range(int(iters)):
                generator = torch.Generator().manual_seed(
                    (self.seed * 1_000_003 + self.iteration) % 2**63
                )
                size = self.config.batch_size
                if count >= size:
                    index = torch.randperm(count, generator=generator)[:size]
                else:
                    index = torch.randint(count, (size,), generator=generator)
                batch = {key: value[index] for key, value in data.items()}
                for net in self.networks.values():
                    net.train()
                self.losses = self.train_step(batch, generator)
                self.iteration += 1
                bar.set_postfix({k: f"{v:.4g}" for k, v in self.losses.items()}, refresh=False)
                bar.update(1)
                if save_to and save_every and self.iteration % save_every == 0:
                    self.save(save_to)
        finally:
            bar.close()
        return dict(self.losses)

    def sample(self, actions: Sequence[str], frames: int | None = None, seed: int = 0,
               **options) -> list[Motion]:
        """Return one motion per entry of ``actions``; the same seed gives the same motions."""
        labels = self.action_indices(actions)
        frames = self.frames if frames is None else frames
        if int(frames) != frames or frames < 1:
            raise MethodError(f"frames must be a positive integer; got {frames!r}")
        if not self.trained:
            raise MethodError(
                f"this {self.name} model has not been trained; call fit(clips, iters) "
                f"or load a checkpoint first"
            )
        if len(labels) == 0:
            return []
        self.check_options(options)
        generator = torch.Generator().manual_seed(int(seed))
        for net in self.networks.values():
            net.eval()
        with torch.no_grad():
            joints = np.concatenate([
                self.generate(labels[i:i + self.sample_chunk], int(frames), generator, **options)
                for i in range(0, len(labels), self.sample_chunk)
            ])
        if not np.isfinite(joints).all():
            raise MethodError(
                f"{self.name} generated non-finite joints (after {self.iteration} training "
                f"iterations); the training diverged: retrain with another seed or a lower "
                f"learning rate"
            )
        return [
            Motion(joints[i], self.skeleton, self.fps, action, self.name,
                   meta={"seed": int(seed), "index": i, "iteration": self.iteration})
            for i, action in enumerate(actions)
        ]

    def check_options(self, options: dict) -> None:
        """Raise :class:`MethodError` for sampling options this method does not take."""
        accepted = set(inspect.signature(self.generate).parameters) - {
            "labels", "frames", "generator"}
        unknown = sorted(set(options) - accepted)
        if unknown:
            raise MethodError(
                f"{self.name} does not take the sampling option(s) {', '.join(unknown)}; "
                f"it takes: {', '.join(sorted(accepted)) or 'none'}"
            )

    def to_checkpoint(self) -> dict:
        """Return everything needed to rebuild the model, as saveable types."""
        return {
            "format": CHECKPOINT_FORMAT,
            "method": self.name,
            "method_version": self.version,
            "config": self.config.to_dict(),
            "skeleton": self.skeleton,
            "actions": list(self.actions),
            "fps": self.fps,
            "frames": self.frames,
            "networks": {key: net.state_dict() for key, net in self.networks.items()},
            "optimizers": {key: opt.state_dict() for key, opt in self.optimizers.items()},
            "iteration": self.iteration,
            "seed": self.seed,
            "losses": dict(self.losses),
            "extras": to_tensors(self.extras),
        }

    def save(self, path: str | Path) -> Path:
        """Write the checkpoint (weights, config, optimizer, statistics) to ``path``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        # Write beside and rename, so an interrupted save never leaves a truncated file.
        partial = path.with_name(path.name + ".partial")
        torch.save(self.to_checkpoint(), partial)
        os.replace(partial, path)
        return path

    @classmethod
    def load(cls, path: str | Path, skeleton: str | None = None) -> "Method":
        """Return the model saved at ``path``; with ``skeleton``, insist it was trained on it.

        Called on :class:`Method` itself, dispatch on the method named in the file.
        """
        path = Path(path)
        checkpoint = read_checkpoint(path)
        method = checkpoint["method"]
        if cls is Method:
            try:
                cls = METHODS.get(method)
            except KeyError as exc:
                raise CheckpointError(f"{path}: {exc.args[0]}") from None
        elif method != cls.name:
            raise CheckpointError(
                f"{path} holds a checkpoint of {method!r}, not of {cls.name!r}; load it with "
                f"get_method({method!r}).load or load_checkpoint"
            )
        saved_version = checkpoint.get("method_version", 1)
        if saved_version != cls.version:
            checkpoint = cls.upgrade_checkpoint(dict(checkpoint), saved_version, path)
        if skeleton is not None and checkpoint["skeleton"] != skeleton:
            raise CheckpointError(
                f"{path} was trained on skeleton {checkpoint['skeleton']!r}, not {skeleton!r}; "
                f"use a checkpoint trained on {skeleton!r} data"
            )
        try:
            config = cls.Config.from_dict(checkpoint["config"])
            model = cls(config, checkpoint["skeleton"], checkpoint["actions"],
                        checkpoint["fps"], checkpoint["frames"])
        except (TypeError, ValueError) as exc:
            raise CheckpointError(f"{path} holds an unusable {method} configuration: {exc}") from None
        for group, objects in (("networks", model.networks), ("optimizers", model.optimizers)):
            states = checkpoint[group]
            if not isinstance(states, dict) or set(states) != set(objects):
                raise CheckpointError(
                    f"{path} has {group} {sorted(states) if isinstance(states, dict) else states}"
                    f", but {method} has {sorted(objects)}; the file is from another version"
                )
            for key, obj in objects.items():
                try:
                    obj.load_state_dict(states[key])
                except (RuntimeError, ValueError, KeyError, TypeError) as exc:
                    raise CheckpointError(
                        f"{path}: the {key} {group[:-1]} state does not fit {method} with this "
                        f"configuration ({str(exc).splitlines()[0]}); the file is damaged or "
                        f"from another version"
                    ) from None
        model.iteration = int(checkpoint["iteration"])
        model.seed = checkpoint.get("seed")
        model.losses = dict(checkpoint.get("losses") or {})
        model.extras = to_arrays(checkpoint["extras"])
        return model

    @classmethod
    def upgrade_checkpoint(cls, checkpoint: dict, version, path: Path) -> dict:
        """Return a checkpoint of an older ``version`` made readable, or raise :class:`CheckpointError`.

        The default reads none: a method whose change kept old weights meaningful
        overrides this (e.g. to fill in the config values the old version had).
        """
        raise CheckpointError(
            f"{path} holds a {cls.name} checkpoint of version {version!r}, but this "
            f"{cls.name} is version {cls.version}"
            + (f" ({cls.version_change})" if cls.version_change else "")
            + f"; its weights do not fit: train it again with manage.py train {cls.name}"
        )


def read_checkpoint(path: str | Path) -> dict:
    """Return the raw checkpoint dict at ``path``, or raise :class:`CheckpointError`."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist; train one with manage.py train")
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for truncated or foreign files
        raise CheckpointError(
            f"{path} is not a readable checkpoint, probably truncated or not written by "
            f"this tool ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
            f"train it again or copy it again"
        ) from None
    if not isinstance(checkpoint, dict):
        raise CheckpointError(f"{path} holds a {type(checkpoint).__name__}, not a method checkpoint")
    missing = [key for key in CHECKPOINT_KEYS if key not in checkpoint]
    if missing:
        raise CheckpointError(
            f"{path} lacks {', '.join(missing)}; it is not a method checkpoint of this tool"
        )
    if checkpoint["format"] != CHECKPOINT_FORMAT:
        raise CheckpointError(
            f"{path} is in checkpoint format {checkpoint['format']!r}; this version reads "
            f"format {CHECKPOINT_FORMAT}"
        )
    return checkpoint
