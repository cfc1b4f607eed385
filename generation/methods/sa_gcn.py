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
4. five graph convolutions ``H' = D⁻¹ (Ã_s + I) H W`` (Eq. 7, with a self-loop added), widths 32, 64, 64, 128, 128,
   residual connections 1 -> 3 and 3 -> 5, then a linear output per joint.

The graph is never built as the dense ``NT × NT`` matrix: ``Ã_s = diag(s_tt) ⊗ Ā +
P ⊗ I`` with ``P`` (``T × T``) holding the ≤ k kept past scores of each frame, so a
graph convolution multiplies each frame by ``Ā`` (``J × J``) and mixes frames by ``P``,
then divides by the node degrees. (Gathering the k past frames instead computes
less but moves more memory; on a CPU it was several times slower.)

Training (Sec. 3.1.3, 4.2): a conditional GAN (binary cross-entropy) with a video
discriminator ``D_V(x, y)`` on whole motions and a frame discriminator ``D_F`` on
``k_frame = 20`` random frames with the label (both also shown real clips under wrong
labels, see below); Adam lr 2e-4, betas (0.5, 0.999), batch 100 (the code: 20). Soft labels ``y = Σ λ_k y_k`` give mixed actions (``mix``).

Choices where the paper is silent, documented here ([code]: the authors' code):

- a node carries its D coordinates (``H_in`` is ``T × J × D``); the code instead runs
  the x and y coordinates as two graphs of one feature per node;
- sizes from the code: label embedding ``Linear(C -> 20)``, noise 30, input layer to 60,
  GRU of 100 units; the three linear layers are ``(100 + C) -> 512 -> 1024 -> F`` with
  ReLU between (the code feeds the class row beside ``c_t``); ReLU after each graph
  convolution (the code: none); residual branches are linear projections; Eq. 7 as
  written (the code adds a learned dense ``NT × NT`` map after each convolution);
- one attention head with ``Q, K, V = W H`` of width F (Eq. 3-4; the code uses 3 heads
  and a gated residual); queries and keys see ``LayerNorm(H)`` and the output is the gated
  residual ``H + γ S V`` (``γ`` learned, starting at 0), and every node of the sequence
  graph keeps a self-loop of weight 1 beside Eq. 6's ``s_tt Ā`` (see
  :class:`CausalSelfAttention` and :class:`SequenceGraph`: without them the attention
  saturated on one frame; version 2 of the method);
- the generator's linear layers (the three before the attention, the graph convolutions,
  the residual branches and the output) are initialised for the ReLUs that follow them
  (He et al. 2015: ``N(0, 2 / fan_in)``, ``N(0, 1 / fan_in)`` where no ReLU follows;
  zero biases; :func:`he_initialise`), not by torch's default (the code's).
  Measured on h36m2d with the ``demo`` preset (standardised poses, whose spread across
  clips is 0.96 per coordinate and between the class means 0.45): under the default each
  of these layers shrank its input, and a fresh generator's poses varied across motions
  by 0.011 and between classes by 0.008; in 500 iterations that never grew past 0.04-0.16
  across motions and 0.03-0.11 between classes (diversity 0.4-1.4 measured every 100
  iterations, against 6.2 for real clips). The same collapse happened with the SA-GC
  layer removed, without the ReLUs after the graph convolutions, with the code's skip from
  the layer's input, with ``c_t`` layer-normalised and with a random start of the
  cumulative sum and residuals scaled by 0.1 (none learned the class; the highest
  diversity at any checkpoint 4.1): what the variants shared was the small start.
  The paper's ``c_0 = o_0`` is kept: ``c_t`` grows with ``t``, mostly by a drift common
  to all motions, but a Gaussian start with residuals scaled by 0.1 did not clearly do
  better (accuracy at 500 iterations 0.12 and 0.18 against 0.37 and 0.09 for seeds 0 and
  1, in exploratory runs of their own).
  With He initialisation a fresh generator varies by 0.73 across motions and 0.44
  between classes; with the term below it learns (version 3 of the method);
- with ``mismatch_weight`` > 0 (1 in the ``demo`` and ``tiny`` presets; 0, Eq. 1 alone,
  in ``paper`` and ``code``: not in the paper) the discriminators are also shown each
  real clip with a wrong label (uniform over the other classes) as fake, with that
  weight, the "matching-aware" discriminator of Reed et al. (2016). Under Eq. 1 alone
  the video discriminator judged real clips with wrong labels real as often as with
  their own (e.g. 0.46 and 0.48 after 500 iterations with He initialisation), i.e. it ignored
  the label, so the generator got no signal about the class: accuracy stayed at chance
  (0.10) even with a generator that did spread its motions (diversity 4-6). With the term
  the video discriminator judged 0.1-0.3 of the mismatched real clips real against
  0.3-0.73 of the matched ones from about iteration 300, and the generator's class means
  spread (0.35-0.73 after 400-500 iterations in the seeds that learned the class).
  Under Eq. 1 alone the discriminators did not win early (each one's loss 0.8-1.4
  through training; 1.39, two terms of ln 2, is chance). Results per training seed are in
  ``docs/SA_GCN_COLLAPSE.md``;
- the discriminators follow the code: per frame ``F -> 1024 -> 1024``, the label
  joined, ``-> 1024 -> 128`` (LeakyReLU 0.2); D_V then a temporal convolution (width 3)
  to one score per frame and a linear layer over the T frames; D_F a score per frame
  and a linear layer over its k frames (with a linear skip from the pose, as the code);
- frames for D_F are drawn with replacement per motion; one update of each
  discriminator, then one of the generator, per iteration; ``real_label`` is the
  target of real clips (1; the code smooths it to 0.9).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch
from torch import nn

from generation.methods.base import Method, MethodConfig, register_method
from generation.methods.common import PoseVectors, adam, one_hot
from generation.methods.seq_gan_common import (
    SoftLabelSampling,
    bce,
    class_rows,
    random_frames,
)
from generation.skeletons import Skeleton, get_skeleton

BETAS = (0.5, 0.999)


@dataclass
class SAGCNConfig(MethodConfig):
    """SA-GCN hyper-parameters (Sec. 4.2 and the authors' code)."""

    PRESETS: ClassVar[dict[str, dict]] = {
        "paper": {},
        "code": {"batch_size": 20, "real_label": 0.9},
        "demo": {"batch_size": 32, "linear_width": 128, "gc_width": 16, "d_hidden": 256,
                 "d_features": 64, "lr": 5e-4, "mismatch_weight": 1.0},
        "tiny": {"batch_size": 8, "noise": 4, "label_embed": 4, "rnn_input": 8, "hidden": 8,
                 "linear_width": 8, "gc_width": 4, "d_hidden": 16, "d_features": 8,
                 "frame_k": 4, "mismatch_weight": 1.0},
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
    # D's term on real clips with a wrong label: not in the paper (0, its Eq. 1 alone, in
    # the paper and code presets; 1 in demo and tiny)
    mismatch_weight: float = 0.0

    def validate(self) -> None:
        super().validate()
        if min(self.noise, self.label_embed, self.rnn_input, self.hidden, self.linear_width,
               self.gc_width, self.d_hidden, self.d_features, self.frame_k) < 1:
            raise ValueError("SAGCNConfig sizes must be >= 1")
        if not 0.0 < self.real_label <= 1.0:
            raise ValueError(f"SAGCNConfig.real_label must be in (0, 1]; got {self.real_label}")
        if not 0.0 <= self.mismatch_weight < float("inf"):
            raise ValueError("SAGCNConfig.mismatch_weight must be a finite number >= 0 (0: the "
                             f"paper's Eq. 1 alone); got {self.mismatch_weight}")


def skeleton_adjacency(skeleton: Skeleton) -> torch.Tensor:
    """Return ``Ā = A + I`` ``(J, J)`` of a skeleton's bones."""
    adjacency = torch.eye(skeleton.n_joints)
    for parent, child in skeleton.bones:
        adjacency[parent, child] = adjacency[child, parent] = 1.0
    return adjacency


def temporal_neighbours(scores: torch.Tensor, k: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Return the top-``k`` strictly past frames of each frame and their scores.

    ``scores`` ``(B, T, T)`` is the causal attention ``S_mask``. Returns ``index`` and
    ``weight`` ``(B, T, min(k, T - 1))``; a frame with fewer past frames than ``k``
    keeps them all and pads with weight 0.
    """
    size, frames = scores.shape[:2]
    k = min(k, frames - 1)
    past = torch.ones(frames, frames, dtype=torch.bool).tril(-1)
    if k <= 0:
        empty = scores.new_zeros(size, frames, 0)
        return empty.long(), empty
    # Scores lie in [0, 1]; -1 ranks the present and future last.
    _, index = scores.masked_fill(~past, -1.0).topk(k, dim=-1, sorted=False)
    valid = index < torch.arange(frames)[:, None]
    weight = torch.where(valid, scores.gather(-1, index), torch.zeros(()))
    return torch.where(valid, index, torch.zeros((), dtype=index.dtype)), weight


class CausalSelfAttention(nn.Module):
    """Scaled dot-product attention over frames, each frame seeing itself and its past.

    Eq. 3-4 as written (``Q, K, V = W H``, ``H_in = S V``) collapsed in training: ``H`` is
    built from the cumulative sum ``c_t``, whose size grows with ``t``, so the logits grew
    with time (their spread went from about 47 to 531 over training) and every row put
    nearly all its weight on one frame; with ``H_in = S V`` and nothing else, every frame
    then carried that frame's features and all samples of a class looked alike. Two
    changes (not in the paper):

    - queries and keys are computed from ``LayerNorm(H)``, so the logits do not scale
      with the size of ``c_t``; values are ``W_v H`` as in Eq. 3;
    - a gated residual ``H_in = H + γ S V`` with a learned scalar ``γ`` starting at 0
      (as in SAGAN-style attention), so each frame keeps its own features and the
      attention's contribution is learned.
    """

    def __init__(self, features: int):
        super().__init__()
        self.norm = nn.LayerNorm(features)
        self.query = nn.Linear(features, features)
        self.key = nn.Linear(features, features)
        self.value = nn.Linear(features, features)
        self.gate = nn.Parameter(torch.zeros(()))  # γ

    def forward(self, frames: torch.Tensor):
        """Return ``S_mask`` ``(B, T, T)`` and ``H_in = H + γ S V`` ``(B, T, F)`` of ``H`` ``(B, T, F)``."""
        length, width = frames.shape[1:]
        normed = self.norm(frames)
        logits = self.query(normed) @ self.key(normed).transpose(1, 2) / width ** 0.5
        future = torch.ones(length, length, dtype=torch.bool).triu(1)
        scores = logits.masked_fill(future, float("-inf")).softmax(dim=-1)
        return scores, frames + self.gate * (scores @ self.value(frames))


class SequenceGraph:
    """The normalised sequence graph ``D⁻¹ (Ã_s + I)`` of a batch, in Kronecker-factored form.

    ``Ã_s = diag(s_tt) ⊗ Ā + P ⊗ I`` (Eq. 6), where ``P`` ``(B, T, T)`` holds each
    frame's kept past scores (at most ``k`` per row); the ``NT × NT`` matrix is never
    formed. In Eq. 6 a node's only self-loop is the one in ``s_tt Ā``, so a frame whose
    own score ``s_tt`` goes to 0 loses its own joints and copies its past; here every
    node also keeps a self-loop of weight 1 (``+ I``, not in the paper).
    """

    def __init__(self, scores: torch.Tensor, adjacency: torch.Tensor, k: int):
        index, weight = temporal_neighbours(scores, k)
        self.adjacency = adjacency
        # Padding entries point at frame 0 with weight 0; adding keeps real links intact.
        self.past = torch.zeros_like(scores).scatter_add(-1, index, weight)
        own = scores.diagonal(dim1=1, dim2=2)[..., None]  # s_tt, (B, T, 1)
        # Degrees of Ã_s + I: the own frame's Ā row, the kept past frames, the self-loop.
        degree = own * adjacency.sum(-1) + weight.sum(-1, keepdim=True) + 1.0  # (B, T, J)
        self.own = (own / degree)[..., None]  # (B, T, J, 1)
        self.inverse_degree = (1 / degree)[..., None]

    def aggregate(self, nodes: torch.Tensor) -> torch.Tensor:
        """Return ``D⁻¹ (Ã_s + I) H`` for node features ``H`` ``(B, T, J, F)``."""
        spatial = self.adjacency @ nodes
        temporal = (self.past @ nodes.flatten(2)).view_as(nodes)
        return self.own * spatial + self.inverse_degree * (temporal + nodes)


def he_initialise(generator: "SAGCNGenerator") -> None:
    """Initialise the generator's linear layers for the ReLUs that follow them (He et al. 2015).

    The three linear layers and the graph convolutions get ``N(0, 2 / fan_in)`` weights
    (``N(0, 1 / fan_in)`` where no ReLU follows: the last linear layer, the residual
    branches and the output) and zero biases. Under torch's default (``U(±1/√fan_in)``,
    variance ``1 / (3 fan_in)``) each of these eleven layers shrank its input, and a
    freshly built generator's poses varied across motions by about 1 % of the data's
    spread; with this they start at about the data's scale.
    """
    relu = list(generator.linears[:-1]) + list(generator.convolutions)
    linear = [generator.linears[-1], generator.skip_1_3, generator.skip_3_5, generator.output]
    for layers, gain in ((relu, "relu"), (linear, "linear")):
        for layer in layers:
            if isinstance(layer, nn.Linear):
                nn.init.kaiming_normal_(layer.weight, nonlinearity=gain)
                if layer.bias is not None:
                    nn.init.zeros_(layer.bias)


class SAGCNGenerator(nn.Module):
    """(noise, class) -> GRU -> cumulative sum -> 3 linear -> SA-GC layer -> poses."""

    def __init__(self, skeleton: Skeleton, classes: int, cfg: SAGCNConfig):
        super().__init__()
        self.joints, self.dims = skeleton.n_joints, skeleton.dims
        self.top_k = cfg.top_k
        pose = self.joints * self.dims
        self.register_buffer("adjacency", skeleton_adjacency(skeleton))
        self.embed = nn.Linear(classes, cfg.label_embed)
        self.inputs = nn.Linear(cfg.label_embed + cfg.noise, cfg.rnn_input)
        self.rnn = nn.GRU(cfg.rnn_input, cfg.hidden, batch_first=True)
        width = cfg.linear_width
        self.linears = nn.Sequential(
            nn.Linear(cfg.hidden + classes, width), nn.ReLU(),
            nn.Linear(width, 2 * width), nn.ReLU(), nn.Linear(2 * width, pose),
        )
        self.attention = CausalSelfAttention(pose)
        w = cfg.gc_width
        widths = [self.dims, w, 2 * w, 2 * w, 4 * w, 4 * w]
        self.convolutions = nn.ModuleList(nn.Linear(a, b) for a, b in zip(widths[:-1], widths[1:]))
        self.skip_1_3 = nn.Linear(widths[1], widths[3], bias=False)
        self.skip_3_5 = nn.Linear(widths[3], widths[5], bias=False)
        self.output = nn.Linear(widths[5], self.dims)
        he_initialise(self)

    def frames(self, classes: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """Return the input frames ``H`` ``(B, T, F)`` of the SA-GC layer."""
        steps = noise.shape[1]
        label = self.embed(classes)[:, None].expand(-1, steps, -1)
        residuals = self.rnn(self.inputs(torch.cat([label, noise], dim=-1)))[0]
        cumulative = residuals.cumsum(dim=1)
        return self.linears(torch.cat([cumulative, classes[:, None].expand(-1, steps, -1)], -1))

    def forward(self, classes: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """Return poses ``(B, T, F)`` of class rows ``(B, C)`` and noise ``(B, T, noise)``."""
        scores, nodes = self.attention(self.frames(classes, noise))
        graph = SequenceGraph(scores, self.adjacency, self.top_k)
        hidden = nodes.unflatten(-1, (self.joints, self.dims))
        outputs = []
        for i, layer in enumerate(self.convolutions):
            # Rows of D⁻¹(Ã_s + I) sum to 1, so aggregation commutes with W and its bias:
            # aggregate the narrower side.
            if layer.in_features < layer.out_features:
                hidden = torch.relu(layer(graph.aggregate(hidden)))
            else:
                hidden = torch.relu(graph.aggregate(layer(hidden)))
            if i == 2:
                hidden = hidden + self.skip_1_3(outputs[0])
            elif i == 4:
                hidden = hidden + self.skip_3_5(outputs[2])
            outputs.append(hidden)
        return self.output(hidden).flatten(2)


def frame_mlp(pose: int, classes: int, hidden: int, features: int):
    """Return the per-frame layers of the code's discriminators: before and after the label."""
    slope = 0.2
    before = nn.Sequential(nn.Linear(pose, hidden), nn.LeakyReLU(slope),
                           nn.Linear(hidden, hidden), nn.LeakyReLU(slope))
    after = nn.Sequential(nn.Linear(hidden + classes, hidden), nn.LeakyReLU(slope),
                          nn.Linear(hidden, features), nn.LeakyReLU(slope))
    return before, after


class VideoDiscriminator(nn.Module):
    """D_V(x, y): per-frame MLP with the label, temporal convolution, linear over T frames."""

    def __init__(self, pose: int, classes: int, frames: int, hidden: int, features: int):
        super().__init__()
        self.before, self.after = frame_mlp(pose, classes, hidden, features)
        self.temporal = nn.Conv1d(features, 1, 3, padding=1)
        self.score = nn.Linear(frames, 1)

    def forward(self, poses: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        label = classes[:, None].expand(-1, poses.shape[1], -1)
        per_frame = self.after(torch.cat([self.before(poses), label], dim=-1))
        return self.score(self.temporal(per_frame.transpose(1, 2))[:, 0]).squeeze(-1)


class FrameDiscriminator(nn.Module):
    """D_F(frames, y): per-frame MLP (with a linear skip) and label, linear over the k frames."""

    def __init__(self, pose: int, classes: int, count: int, hidden: int, features: int):
        super().__init__()
        self.before, self.after = frame_mlp(pose, classes, hidden, features)
        self.skip = nn.Linear(pose, hidden)
        self.per_frame = nn.Linear(features, 1)
        self.score = nn.Linear(count, 1)

    def forward(self, frames: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        label = classes[:, None].expand(-1, frames.shape[1], -1)
        features = self.before(frames) + self.skip(frames)
        per_frame = self.per_frame(self.after(torch.cat([features, label], dim=-1)))[..., 0]
        return self.score(per_frame).squeeze(-1)


@register_method("sa_gcn")
class SAGCN(SoftLabelSampling, PoseVectors, Method):
    """SA-GCN: GRU of residuals, causal attention sparsifying a skeleton-sequence graph, GCN."""

    Config = SAGCNConfig
    version = 3
    version_change = ("version 2 normalises the attention's queries and keys, adds a gated "
                      "residual and a self-loop per node; version 3 initialises the generator's "
                      "linear layers for ReLU (He) and trains with mismatched labels")
    # Node features are (B, T, J, 128): small chunks stay in cache (measured: 1,000
    # motions of 60 frames take 14 s in one chunk of 1,024 and 3.5 s in chunks of 32).
    sample_chunk = 32

    def build(self):
        cfg, classes, pose = self.config, len(self.actions), self.pose_width
        return {
            "generator": SAGCNGenerator(get_skeleton(self.skeleton), classes, cfg),
            "video_discriminator": VideoDiscriminator(pose, classes, self.frames, cfg.d_hidden,
                                                      cfg.d_features),
            "frame_discriminator": FrameDiscriminator(pose, classes, cfg.frame_k, cfg.d_hidden,
                                                      cfg.d_features),
        }

    def build_optimizers(self):
        lr = self.config.lr
        return {key: adam([net], lr, BETAS) for key, net in self.networks.items()}

    def _generate(self, classes: torch.Tensor, frames: int, generator: torch.Generator):
        noise = torch.randn(len(classes), frames, self.config.noise, generator=generator)
        return self.networks["generator"](classes, noise)

    def train_step(self, batch, generator):
        cfg = self.config
        real = batch["pose"]
        count = len(self.actions)
        classes = one_hot(batch["label"], count)
        video, frame = self.networks["video_discriminator"], self.networks["frame_discriminator"]
        fake = self._generate(classes, real.shape[1], generator)
        real_frames = random_frames(real, cfg.frame_k, generator)
        fake_frames = random_frames(fake, cfg.frame_k, generator)

        dv_loss = bce(video(real, classes), cfg.real_label) + bce(video(fake.detach(), classes), 0.0)
        df_loss = (bce(frame(real_frames, classes), cfg.real_label)
                   + bce(frame(fake_frames.detach(), classes), 0.0))
        if cfg.mismatch_weight > 0 and count > 1:
            # Real clips paired with another class than theirs count as fake (see the module).
            shift = torch.randint(1, count, batch["label"].shape, generator=generator)
            wrong = one_hot((batch["label"] + shift) % count, count)
            dv_loss = dv_loss + cfg.mismatch_weight * bce(video(real, wrong), 0.0)
            df_loss = df_loss + cfg.mismatch_weight * bce(frame(real_frames, wrong), 0.0)
        for key, loss in (("video_discriminator", dv_loss), ("frame_discriminator", df_loss)):
            self.optimizers[key].zero_grad()
            loss.backward()
            self.optimizers[key].step()

        for net in (video, frame):
            net.requires_grad_(False)
        g_loss = (bce(video(fake, classes), cfg.real_label)
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
