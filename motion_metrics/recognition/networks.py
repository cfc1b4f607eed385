"""The classifier's config and network: A2M's GRU, optionally with a temporal convolution beside it."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import ClassVar

import torch
from torch import nn

FEATURES = 30  # A2M's feature layer
TEMPORAL_KERNEL = 5  # frames seen by each temporal convolution


@dataclass
class ClassifierConfig:
    """Classifier hyper-parameters and training augmentation.

    ``paper`` is A2M's network as released (a 2-layer GRU of 128, no augmentation);
    ``augmented`` adds what was measured to recognise held-out subjects better on h36m2d
    (``benchmarks/bench_classifier.py``; ``docs/INSTRUMENTS.md`` gives the variants' held-out
    accuracy): mirrored clips and rotations of up to 10 degrees (a temporal convolution
    beside the GRU, ``temporal``, lowered it); ``tiny`` is for tests.
    ``temporal`` is the width of the convolution branch (0: none); ``mirror`` trains on
    each clip or its mirror image (left and right swapped) at random; ``rotate`` is the
    largest rotation in degrees (about the vertical axis in 3D, in the image plane in 2D).
    """

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "augmented": {"mirror": True, "rotate": 10.0},
        "tiny": {"hidden": 16, "layers": 1, "batch_size": 16, "lr": 3e-3},
    }

    hidden: int = 128
    layers: int = 2
    batch_size: int = 128
    lr: float = 1e-3
    temporal: int = 0
    mirror: bool = False
    rotate: float = 0.0

    def __post_init__(self):
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name == "mirror":
                if not isinstance(value, bool):
                    raise ValueError(f"ClassifierConfig.mirror must be true or false; got {value!r}")
                continue
            number = isinstance(value, (int, float)) and not isinstance(value, bool)
            least = 0 if item.name in ("temporal", "rotate") else None
            if not number or not math.isfinite(value) or (
                    value < least if least is not None else value <= 0):
                kind = "a number of at least 0" if least is not None else "a positive number"
                raise ValueError(f"ClassifierConfig.{item.name} must be {kind}; got {value!r}")
        if self.rotate > 180:
            raise ValueError(f"ClassifierConfig.rotate is at most 180 degrees; got {self.rotate!r}")

    @classmethod
    def preset(cls, name: str) -> "ClassifierConfig":
        """Return the config of a named preset."""
        if name not in cls.PRESETS:
            raise ValueError(f"unknown preset {name!r}; choose one of: {', '.join(sorted(cls.PRESETS))}")
        return cls(**cls.PRESETS[name])

    def to_dict(self) -> dict:
        return asdict(self)


class GRURecogniser(nn.Module):
    """poses ``(B, T, F)`` -> GRU -> last output -> 30-d tanh (features) -> class logits.

    With ``temporal`` channels, two temporal convolutions (ReLU, width
    :data:`TEMPORAL_KERNEL`) averaged over time run beside the GRU, and the feature layer
    reads both.
    """

    def __init__(self, pose: int, hidden: int, layers: int, classes: int, temporal: int = 0):
        super().__init__()
        self.gru = nn.GRU(pose, hidden, num_layers=layers, batch_first=True)
        self.convolution = None
        if temporal:
            pad = TEMPORAL_KERNEL // 2
            self.convolution = nn.Sequential(
                nn.Conv1d(pose, temporal, TEMPORAL_KERNEL, padding=pad), nn.ReLU(),
                nn.Conv1d(temporal, temporal, TEMPORAL_KERNEL, padding=pad), nn.ReLU())
        self.feature = nn.Linear(hidden + temporal, FEATURES)
        self.output = nn.Linear(FEATURES, classes)

    def features(self, poses: torch.Tensor) -> torch.Tensor:
        outputs, _ = self.gru(poses)
        summary = outputs[:, -1]
        if self.convolution is not None:
            summary = torch.cat([summary, self.convolution(poses.transpose(1, 2)).mean(-1)], -1)
        return torch.tanh(self.feature(summary))

    def forward(self, poses: torch.Tensor) -> torch.Tensor:
        return self.output(self.features(poses))
