"""SA-GCN (seed 004): a graph convolutional generator sparsified by self-attention, two critics.

Generator (Sec. 3.1-3.2), per motion of T frames:

1. per step, noise ``z_t`` and the embedded class ``E(y)`` -> RNN -> ``o_t``; residual
   cumulative sum ``c_t = c_{t-1} + o_t`` (``c_0 = o_0``);
2. three linear layers map ``c_t`` to a frame ``h_t`` of ``F = J * D`` numbers;
3. the SA-GC layer: causal scaled dot-product self-attention over frames gives
   ``S_mask`` (lower-triangular, Eq. 4-5) and ``H_in = S V``. Each row keeps its own frame
   and its top ``k = 5`` past frames by score ("6 elements in each row"; the code takes
   the top 5 of the row, its own frame included); the sequence graph is
   ``Ã_s = S_mask ⊙ Ã``: frame t's skeleton ``Ā = A + I`` weighted ``s_tt``, and joint j
   of frame t linked to joint j of each kept past frame t' with weight ``s_tt'`` (Eq. 6);
4. five graph convolutions ``H' = D⁻¹ Ã_s H W`` (Eq. 7), widths 32, 64, 64, 128, 128,
   residual connections 1 -> 3 and 3 -> 5, then a linear output per joint.

The graph is never built as the dense ``NT × NT`` matrix (see
:class:`~generation.methods.sa_gcn_networks.SequenceGraph`).

Training (Sec. 3.1.3, 4.2): Eq. 1, a conditional GAN (binary cross-entropy) with a video
discriminator ``D_V(x, y)`` on whole motions and a frame discriminator ``D_F`` on
``k_frame = 20`` random frames with the label; Adam lr 2e-4, betas (0.5, 0.999), batch
100 (the code: 20). Soft labels ``y = Σ λ_k y_k`` give mixed actions (``mix``).

The ``paper`` preset is exactly that. Each departure is a config switch, saved with the
checkpoint (``docs/SA_GCN_COLLAPSE.md`` measures which of them matter):

- ``qk_norm``: queries and keys from ``LayerNorm(H)`` (``c_t`` grows with ``t``, and the
  unnormalised logits saturated on one frame);
- ``gated_residual``: ``H_in = H + γ S V``, ``γ`` learned from 0 (the authors' code);
- ``self_loop``: every node of the sequence graph keeps a self-loop of weight 1 beside
  Eq. 6's ``s_tt Ā`` (``D⁻¹ (Ã_s + I) H W``);
- ``init``: ``default`` (torch's, as the paper's code) or ``he`` (He et al. 2015 for the
  generator's linear layers and graph convolutions: under the default each of them
  shrank its input and a fresh generator's poses varied across motions by about 1 % of
  the data's spread);
- ``mismatch_weight``: the discriminators are also shown each real clip under a wrong
  label (uniform over the other classes) as fake, with that weight: Reed et al.'s
  (2016) matching-aware discriminator, in neither the paper nor the code;
- ``class_weight``: the authors' code's class head, a linear layer from D_V's per-frame
  scores to class logits with cross-entropy on real and generated clips for D_V and on
  generated ones for the generator (AC-GAN style), at that weight; the released code has
  it commented out.

Choices where the paper is silent, documented here ([code]: the authors' code):

- a node carries its D coordinates (``H_in`` is ``T × J × D``); the code instead runs
  the x and y coordinates as two graphs of one feature per node;
- sizes from the code: label embedding ``Linear(C -> 20)``, noise 30, input layer to 60,
  GRU of 100 units; the three linear layers are ``(100 + C) -> 512 -> 1024 -> F`` with
  ReLU between (the code feeds the class row beside ``c_t``); ReLU after each graph
  convolution ("the output (before activation)", Eq. 7; the code: none); residual
  branches are linear projections; Eq. 7 as written (the code adds a learned dense
  ``NT × NT`` map after each convolution); one attention head with ``Q, K, V = W H`` of
  width F (the code uses 3 heads);
- the discriminators follow the code: per frame ``F -> 1024 -> 1024``, the label
  joined, ``-> 1024 -> 128`` (LeakyReLU 0.2); D_V then a temporal convolution (width 3)
  to one score per frame and a linear layer over the T frames; D_F a score per frame
  and a linear layer over its k frames (with a linear skip from the pose, as the code);
- frames for D_F are drawn with replacement per motion; one update of each
  discriminator, then one of the generator, per iteration; ``real_label`` is the
  target of real clips (1; the code smooths it to 0.9); the class head's logits are
  taken as logits (the code applies a softmax before its cross-entropy).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
import torch.nn.functional as F

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, adam, one_hot
from generation.methods.sa_gcn_networks import (
    INITIALISATIONS,
    CausalSelfAttention,
    FrameDiscriminator,
    SAGCNGenerator,
    SequenceGraph,
    VideoDiscriminator,
    he_initialise,
    skeleton_adjacency,
    temporal_neighbours,
)
from generation.methods.seq_gan_common import (
    SoftLabelSampling,
    bce,
    class_rows,
    random_frames,
)
from motion.skeletons import get_skeleton

BETAS = (0.5, 0.999)
# The departures as version 3 had them, always on (what its checkpoints were trained with).
VERSION_3 = {"qk_norm": True, "gated_residual": True, "self_loop": True, "init": "he",
             "class_weight": 0.0}

__all__ = ["SAGCN", "SAGCNConfig", "CausalSelfAttention", "SequenceGraph", "he_initialise",
           "skeleton_adjacency", "temporal_neighbours"]


@dataclass
class SAGCNConfig(MethodConfig):
    """SA-GCN hyper-parameters (Sec. 4.2 and the authors' code) and the departures' switches."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "code": {"batch_size": 20, "real_label": 0.9, "gated_residual": True},
        "demo": {"batch_size": 32, "linear_width": 128, "gc_width": 16, "d_hidden": 256,
                 "d_features": 64, "lr": 5e-4, "qk_norm": True, "gated_residual": True,
                 "self_loop": True, "init": "he", "mismatch_weight": 1.0},
        "tiny": {"batch_size": 8, "noise": 4, "label_embed": 4, "rnn_input": 8, "hidden": 8,
                 "linear_width": 8, "gc_width": 4, "d_hidden": 16, "d_features": 8,
                 "frame_k": 4, "qk_norm": True, "gated_residual": True, "self_loop": True,
                 "init": "he", "mismatch_weight": 1.0},
    }

    batch_size: int = 100
    noise: int = 30  # size of z_t
    label_embed: int = 20
    rnn_input: int = 60
    hidden: int = 100  # GRU units
    linear_width: int = 512  # the three linear layers: width, 2 * width, F
    top_k: int = 5  # past frames kept per frame
    gc_width: int = 32  # graph convolutions: w, 2w, 2w, 4w, 4w
    d_hidden: int = 1024
    d_features: int = 128
    frame_k: int = 20  # frames shown to the frame discriminator
    lr: float = 2e-4
    real_label: float = 1.0
    # Departures from Eq. 1, 4, 6, 7 (all off in the paper preset; see the module).
    qk_norm: bool = False
    gated_residual: bool = False
    self_loop: bool = False
    init: str = "default"
    mismatch_weight: float = 0.0
    class_weight: float = 0.0

    def validate(self) -> None:
        super().validate()
        if min(self.noise, self.label_embed, self.rnn_input, self.hidden, self.linear_width,
               self.gc_width, self.d_hidden, self.d_features, self.frame_k) < 1:
            raise ValueError("SAGCNConfig sizes must be >= 1")
        if not 0.0 < self.real_label <= 1.0:
            raise ValueError(f"SAGCNConfig.real_label must be in (0, 1]; got {self.real_label}")
        for name in ("qk_norm", "gated_residual", "self_loop"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"SAGCNConfig.{name} must be true or false; got "
                                 f"{getattr(self, name)!r}")
        if self.init not in INITIALISATIONS:
            raise ValueError(f"SAGCNConfig.init must be one of {', '.join(INITIALISATIONS)} "
                             f"(default: torch's, as the paper; he: He et al.); got {self.init!r}")
        for name in ("mismatch_weight", "class_weight"):
            if not 0.0 <= getattr(self, name) < float("inf"):
                raise ValueError(f"SAGCNConfig.{name} must be a finite number >= 0 (0: the "
                                 f"paper's Eq. 1 alone); got {getattr(self, name)}")

    def departures(self) -> dict:
        """Return the departures from the paper this config takes (empty for ``paper``)."""
        paper = type(self)()
        return {name: getattr(self, name) for name in (*VERSION_3, "mismatch_weight")
                if getattr(self, name) != getattr(paper, name)}


@register_method("sa_gcn")
class SAGCN(SoftLabelSampling, PoseVectors, Method):
    """SA-GCN: GRU of residuals, causal attention sparsifying a skeleton-sequence graph, GCN."""

    Config = SAGCNConfig
    version = 4
    version_change = ("version 2 normalises the attention's queries and keys, adds a gated "
                      "residual and a self-loop per node; version 3 initialises the generator's "
                      "linear layers for ReLU (He) and trains with mismatched labels; version 4 "
                      "makes each of these a config switch, all off in the paper preset")
    # Node features are (B, T, J, 128): small chunks stay in cache (measured: 1,000
    # motions of 60 frames take 14 s in one chunk of 1,024 and 3.5 s in chunks of 32).
    sample_chunk = 32

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "generator": SAGCNGenerator(get_skeleton(self.skeleton), classes, cfg),
            "video_discriminator": VideoDiscriminator(pose, classes, self.frames, cfg.d_hidden,
                                                      cfg.d_features, cfg.class_weight > 0),
            "frame_discriminator": FrameDiscriminator(pose, classes, cfg.frame_k, cfg.d_hidden,
                                                      cfg.d_features),
        }

    def build_optimizers(self):
        lr = self.config.lr
        return {key: adam([net], lr, BETAS) for key, net in self.networks.items()}

    @classmethod
    def upgrade_checkpoint(cls, checkpoint, version, path):
        """Read version 3 checkpoints: the same networks with every departure on."""
        if version != 3:
            return super().upgrade_checkpoint(checkpoint, version, path)
        checkpoint["config"] = {**checkpoint["config"], **VERSION_3}
        return checkpoint

    def _generate(self, classes: torch.Tensor, frames: int, generator: torch.Generator):
        noise = torch.randn(len(classes), frames, self.config.noise, generator=generator)
        return self.networks["generator"](classes, noise)

    def _video_terms(self, poses, classes, labels, target: float) -> torch.Tensor:
        """Return D_V's binary term for ``target``, plus the class head's cross-entropy."""
        video, weight = self.networks["video_discriminator"], self.config.class_weight
        if weight <= 0:
            return bce(video(poses, classes), target)
        score, logits = video.with_logits(poses, classes)
        return bce(score, target) + weight * F.cross_entropy(logits, labels)

    def train_step(self, batch, generator):
        cfg = self.config
        real, labels = batch["pose"], batch["label"]
        count = len(self.actions)
        classes = one_hot(labels, count)
        video, frame = self.networks["video_discriminator"], self.networks["frame_discriminator"]
        fake = self._generate(classes, real.shape[1], generator)
        real_frames = random_frames(real, cfg.frame_k, generator)
        fake_frames = random_frames(fake, cfg.frame_k, generator)

        dv_loss = (self._video_terms(real, classes, labels, cfg.real_label)
                   + self._video_terms(fake.detach(), classes, labels, 0.0))
        df_loss = (bce(frame(real_frames, classes), cfg.real_label)
                   + bce(frame(fake_frames.detach(), classes), 0.0))
        if cfg.mismatch_weight > 0 and count > 1:
            # Real clips paired with another class than theirs count as fake (see the module).
            shift = torch.randint(1, count, labels.shape, generator=generator)
            wrong = one_hot((labels + shift) % count, count)
            dv_loss = dv_loss + cfg.mismatch_weight * bce(video(real, wrong), 0.0)
            df_loss = df_loss + cfg.mismatch_weight * bce(frame(real_frames, wrong), 0.0)
        for key, loss in (("video_discriminator", dv_loss), ("frame_discriminator", df_loss)):
            self.optimizers[key].zero_grad()
            loss.backward()
            self.optimizers[key].step()

        for net in (video, frame):
            net.requires_grad_(False)
        g_loss = (self._video_terms(fake, classes, labels, cfg.real_label)
                  + bce(frame(fake_frames, classes), cfg.real_label))
        self.optimizers["generator"].zero_grad()
        g_loss.backward()
        self.optimizers["generator"].step()
        for net in (video, frame):
            net.requires_grad_(True)
        return {"d_video": dv_loss.item(), "d_frame": df_loss.item(), "g": g_loss.item()}

    def generate(self, labels, frames, generator, mix=None):
        """Sample motions; ``mix`` (action -> weight) replaces every label by that soft label."""
        classes = class_rows(self, labels, mix)
        return self.poses_to_joints(self._generate(classes, frames, generator))
