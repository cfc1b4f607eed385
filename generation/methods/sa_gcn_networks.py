"""The networks of SA-GCN (seed 004): SA-GC generator, video and frame discriminators.

Each departure from the paper is a switch (see :mod:`generation.methods.sa_gcn`, whose
config carries them): without any, the attention is Eq. 3-4 (``S = softmax(QK^T / √F)``,
``H_in = S V``), the sequence graph Eq. 6 and a graph convolution Eq. 7
(``D⁻¹ Ã_s H W``). This module defines no method; it registers nothing.
"""

from __future__ import annotations

import torch
from torch import nn

from motion.skeletons import Skeleton

INITIALISATIONS = ("default", "he")  # torch's own (the paper's and code's), or He et al. 2015


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

    As written (Eq. 3-4; the text calls it "scaled dot-product attention as in [33]", so
    the logits are divided by ``√F``): ``Q, K, V = W H``, ``S = softmax(QK^T / √F)``
    masked to the past, ``H_in = S V``. Two departures, each a switch:

    - ``qk_norm``: queries and keys are computed from ``LayerNorm(H)``. ``H`` is built
      from the cumulative sum ``c_t``, whose size grows with ``t``, so the logits grew
      with time and rows put nearly all their weight on one frame;
    - ``gated``: ``H_in = H + γ S V`` with a learned scalar ``γ`` starting at 0 (SAGAN's
      gate; the authors' code has it), so each frame keeps its own features.
    """

    def __init__(self, features: int, qk_norm: bool = True, gated: bool = True):
        super().__init__()
        self.norm = nn.LayerNorm(features) if qk_norm else None
        self.query = nn.Linear(features, features)
        self.key = nn.Linear(features, features)
        self.value = nn.Linear(features, features)
        self.gate = nn.Parameter(torch.zeros(())) if gated else None  # γ

    def forward(self, frames: torch.Tensor):
        """Return ``S_mask`` ``(B, T, T)`` and ``H_in`` ``(B, T, F)`` of ``H`` ``(B, T, F)``."""
        length, width = frames.shape[1:]
        normed = frames if self.norm is None else self.norm(frames)
        logits = self.query(normed) @ self.key(normed).transpose(1, 2) / width ** 0.5
        future = torch.ones(length, length, dtype=torch.bool).triu(1)
        scores = logits.masked_fill(future, float("-inf")).softmax(dim=-1)
        attended = scores @ self.value(frames)
        return scores, attended if self.gate is None else frames + self.gate * attended


class SequenceGraph:
    """The normalised sequence graph ``D⁻¹ Ã_s`` of a batch, in Kronecker-factored form.

    ``Ã_s = diag(s_tt) ⊗ Ā + P ⊗ I`` (Eq. 6), where ``P`` ``(B, T, T)`` holds each
    frame's kept past scores (at most ``k`` per row); the ``NT × NT`` matrix is never
    formed. In Eq. 6 a node's only self-loop is the one in ``s_tt Ā``, so a frame whose
    own score ``s_tt`` goes to 0 loses its own joints and copies its past; with
    ``self_loop`` every node also keeps a self-loop of weight 1 (``Ã_s + I``, not in the
    paper).
    """

    def __init__(self, scores: torch.Tensor, adjacency: torch.Tensor, k: int,
                 self_loop: bool = True):
        index, weight = temporal_neighbours(scores, k)
        self.adjacency = adjacency
        self.self_loop = self_loop
        # Padding entries point at frame 0 with weight 0; adding keeps real links intact.
        self.past = torch.zeros_like(scores).scatter_add(-1, index, weight)
        own = scores.diagonal(dim1=1, dim2=2)[..., None]  # s_tt, (B, T, 1)
        # Degrees: the own frame's Ā row, the kept past frames (and the self-loop).
        degree = own * adjacency.sum(-1) + weight.sum(-1, keepdim=True) + float(self_loop)
        degree = degree.clamp_min(1e-12)  # (B, T, J); a softmax row never sums to 0
        self.own = (own / degree)[..., None]  # (B, T, J, 1)
        self.inverse_degree = (1 / degree)[..., None]

    def aggregate(self, nodes: torch.Tensor) -> torch.Tensor:
        """Return ``D⁻¹ Ã_s H`` (with self-loops: ``D⁻¹ (Ã_s + I) H``) of node features ``(B, T, J, F)``."""
        spatial = self.adjacency @ nodes
        temporal = (self.past @ nodes.flatten(2)).view_as(nodes)
        if self.self_loop:
            temporal = temporal + nodes
        return self.own * spatial + self.inverse_degree * temporal


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
    """(noise, class) -> GRU -> cumulative sum -> 3 linear -> SA-GC layer -> poses.

    ``cfg`` is an :class:`~generation.methods.sa_gcn.SAGCNConfig`: its sizes, and the
    switches ``qk_norm``, ``gated_residual``, ``self_loop`` and ``init``.
    """

    def __init__(self, skeleton: Skeleton, classes: int, cfg):
        super().__init__()
        self.joints, self.dims = skeleton.n_joints, skeleton.dims
        self.top_k = cfg.top_k
        self.self_loop = cfg.self_loop
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
        self.attention = CausalSelfAttention(pose, qk_norm=cfg.qk_norm, gated=cfg.gated_residual)
        w = cfg.gc_width
        widths = [self.dims, w, 2 * w, 2 * w, 4 * w, 4 * w]
        self.convolutions = nn.ModuleList(nn.Linear(a, b) for a, b in zip(widths[:-1], widths[1:]))
        self.skip_1_3 = nn.Linear(widths[1], widths[3], bias=False)
        self.skip_3_5 = nn.Linear(widths[3], widths[5], bias=False)
        self.output = nn.Linear(widths[5], self.dims)
        if cfg.init == "he":
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
        graph = SequenceGraph(scores, self.adjacency, self.top_k, self.self_loop)
        hidden = nodes.unflatten(-1, (self.joints, self.dims))
        outputs = []
        for i, layer in enumerate(self.convolutions):
            # Rows of the normalised graph sum to 1, so aggregation commutes with W and its
            # bias: aggregate the narrower side.
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
    """D_V(x, y): per-frame MLP with the label, temporal convolution, linear over T frames.

    With ``class_head`` it also returns class logits from the same per-frame scores (the
    authors' code's ``linear3``, whose cross-entropy term it later commented out).
    """

    def __init__(self, pose: int, classes: int, frames: int, hidden: int, features: int,
                 class_head: bool = False):
        super().__init__()
        self.before, self.after = frame_mlp(pose, classes, hidden, features)
        self.temporal = nn.Conv1d(features, 1, 3, padding=1)
        self.score = nn.Linear(frames, 1)
        self.classify = nn.Linear(frames, classes) if class_head else None

    def per_frame(self, poses: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        """Return one score per frame ``(B, T)``."""
        label = classes[:, None].expand(-1, poses.shape[1], -1)
        features = self.after(torch.cat([self.before(poses), label], dim=-1))
        return self.temporal(features.transpose(1, 2))[:, 0]

    def forward(self, poses: torch.Tensor, classes: torch.Tensor) -> torch.Tensor:
        return self.score(self.per_frame(poses, classes)).squeeze(-1)

    def with_logits(self, poses: torch.Tensor, classes: torch.Tensor):
        """Return the real/fake logit ``(B,)`` and the class logits ``(B, C)`` (needs the head)."""
        frames = self.per_frame(poses, classes)
        return self.score(frames).squeeze(-1), self.classify(frames)


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
