"""The ``authors`` MMD protocol: MMD as SA-GCN's released code measures it on Human3.6M in 2D.

What the authors' code does (``util/data_utils.py``, ``train.py`` and ``util/evaluation.py``
of SA-GCN, whose data preparation is c-SkeletonGAN's):

- poses are the 2D projections onto camera 55011271 (``project_to_cameras`` loops over a
  subject's 4 cameras but keeps only that one), **centred on the hip in every frame**
  (``center_around_hip``) and **scaled by the hip's depth** over the training set's mean
  depth (``scale``: ``x * z / mean z``), then standardised per coordinate by the training
  set's mean and standard deviation; the hip and Neck/Nose are dropped (15 joints);
- every 200 iterations 50 batches of 20 clips are drawn from the **training** takes
  (random windows, every 3rd frame) with generated motions of the same labels, about 100
  per class of the 10; per class the MMD of whole sequences is
  ``sqrt(mean_{i≠j} [k(x_i, x_j) + k(y_i, y_j) - 2 k(x_i, y_j)])`` (Gaussian kernel, the
  pairs' own cross terms left out), maximised over bandwidths ``10^-4 ... 10^9``, and the
  mean over classes is kept when it is the lowest so far: the reported number is the
  **minimum over training** of a score on training clips.

Here the same estimator (:func:`motion_metrics.metrics.mmd_per_bandwidth`, ``paired``)
runs on the same representation, with one difference the data force: generated 2D motions
carry no depth, so the depth ratio ``z / mean z`` of each frame is estimated from the
figure's size, ``s_t = mean L / L_t`` with ``L_t`` the summed 2D length of the frame's
bones and ``mean L`` that of the training frames (a body twice as far looks half as big),
for real and generated motions alike; the hip is the midpoint of the two hip joints
(``h36m15_2d`` has no pelvis). ``docs/RESULTS.md`` gives how well ``s_t`` follows the true
depth ratio on real clips. :func:`authors_mmd` measures against the training clips (the
authors' side) and against the held-out clips, each with ``per_class`` motions per class
drawn afresh in each repeat (fewer where a side has fewer).
"""

from __future__ import annotations

import numpy as np

from motion_metrics import metrics as M

PER_CLASS = 100  # 50 batches of 20 over 10 classes
HIPS = ("RHip", "LHip")


def check_skeleton(skeleton) -> tuple[int, int]:
    """Return the indices of the two hip joints, or raise naming what the protocol needs."""
    names = skeleton.joint_names
    if skeleton.dims != 2 or not all(name in names for name in HIPS):
        raise M.MetricError(
            f"the authors' MMD protocol is the 2D setting of seeds 003/004 (joints RHip and LHip "
            f"in pixels, as h36m2d); skeleton {skeleton.name!r} is not; use the heldout or paper "
            f"MMD protocol")
    return names.index(HIPS[0]), names.index(HIPS[1])


def body_size(skeleton, joints: np.ndarray) -> np.ndarray:
    """Return each frame's summed 2D bone length ``(N, T)`` of joints ``(N, T, J, 2)``."""
    return skeleton.bone_lengths(joints).sum(-1)


class Representation:
    """Hip-centred, depth-scaled, standardised poses, with the training clips' statistics."""

    def __init__(self, skeleton, train_joints: np.ndarray):
        self.skeleton = skeleton
        self.hips = check_skeleton(skeleton)
        train_joints = np.asarray(train_joints, dtype=np.float64)
        self.mean_size = float(body_size(skeleton, train_joints).mean())
        flat = self.scaled(train_joints).reshape(-1, skeleton.n_joints * 2)
        self.mean = flat.mean(0)
        self.std = np.maximum(flat.std(0), 1e-6 * max(float(flat.std(0).max()), 1e-12))

    def depth_ratio(self, joints: np.ndarray) -> np.ndarray:
        """Return the estimated ``z / mean z`` of each frame ``(N, T)``."""
        return self.mean_size / np.maximum(body_size(self.skeleton, joints), 1e-9)

    def scaled(self, joints: np.ndarray) -> np.ndarray:
        """Return joints centred on the hip in every frame and scaled by the depth ratio."""
        joints = np.asarray(joints, dtype=np.float64)
        hip = joints[:, :, list(self.hips)].mean(axis=2, keepdims=True)
        return (joints - hip) * self.depth_ratio(joints)[..., None, None]

    def __call__(self, joints: np.ndarray) -> np.ndarray:
        """Return the standardised representation ``(N, T, J * 2)``."""
        scaled = self.scaled(joints)
        return (scaled.reshape(*scaled.shape[:2], -1) - self.mean) / self.std


def paired_mmd(x: np.ndarray, y: np.ndarray, per_frame: bool, bandwidths=M.BANDWIDTHS) -> float:
    """Return the authors' MMD of equal-sized sets ``(n, T, F)``: whole sequences, or the
    frame average (``per_frame``), maximised over bandwidths.

    The same estimate as :func:`motion_metrics.metrics.mmd_per_bandwidth` with ``paired``
    (a test holds them equal), with every frame's distances computed at once.
    """
    n = len(x)
    if n < 2 or len(y) != n:
        raise M.MetricError(f"paired MMD needs two sets of one size of at least 2; got {n} and {len(y)}")
    if per_frame:
        x, y = x.transpose(1, 0, 2), y.transpose(1, 0, 2)  # (T, n, F)
    else:
        x, y = x.reshape(1, n, -1), y.reshape(1, n, -1)
    d_xx, d_yy, d_xy = M.sq_dists(x), M.sq_dists(y), M.sq_dists(x, y)
    off = ~np.eye(n, dtype=bool)
    best = 0.0
    for bandwidth in np.asarray(bandwidths, dtype=np.float64):
        terms = [np.exp(np.maximum(-d / bandwidth, M.FLOAT64_EXP_FLOOR))[:, off].sum(-1)
                 for d in (d_xx, d_yy, d_xy)]
        squared = (terms[0] + terms[1] - 2.0 * terms[2]) / (n * (n - 1))
        best = max(best, float(np.sqrt(np.maximum(squared, 0.0)).mean()))
    return best


def authors_mmd(generated, train, test, metrics=("mmd_avg", "mmd_seq"), repeats: int = 5,
                seed: int = 0, per_class: int = PER_CLASS, skeleton=None,
                bandwidths=M.BANDWIDTHS) -> dict:
    """Return MMD_avg / MMD_seq by the authors' protocol, against training and held-out clips.

    ``generated``, ``train`` and ``test`` are :class:`motion_metrics.protocol.MotionSet`
    (joints in the skeleton's pixels; ``test`` may be ``None``: the training side only, as
    when the score selects a checkpoint). Each repeat ``r`` (generator seeded by
    ``(seed, r, 3)``) draws per class ``n = min(per_class, generated, side)`` motions of
    each side without replacement and pairs them. Returns per metric the summary of the
    scores against the training clips (the authors' number) with ``heldout`` (against the
    held-out clips) and ``real`` (held-out against training clips, both drawn so) beside.
    """
    from motion_metrics.protocol import _summary, check_metrics

    names = [name for name in check_metrics(list(metrics)) if name in ("mmd_avg", "mmd_seq")]
    represent = Representation(skeleton, train.joints)
    sides = {"gen": represent(generated.joints), "train": represent(train.joints)}
    labels = {"gen": generated.labels, "train": train.labels}
    pairs = {"train": ("gen", "train")}
    if test is not None:
        sides["test"], labels["test"] = represent(test.joints), test.labels
        pairs.update(heldout=("gen", "test"), real=("test", "train"))
    values = {(name, pair): np.full(repeats, np.nan) for name in names for pair in pairs}
    for r in range(repeats):
        rng = np.random.default_rng([seed, r, 3])
        for pair, (a, b) in pairs.items():
            per_name = {name: [] for name in names}
            for action in np.unique(generated.labels):
                pool_a = np.flatnonzero(labels[a] == action)
                pool_b = np.flatnonzero(labels[b] == action)
                n = min(per_class, len(pool_a), len(pool_b))
                if n < 2:
                    continue
                x = sides[a][rng.choice(pool_a, n, replace=False)]
                y = sides[b][rng.choice(pool_b, n, replace=False)]
                for name in names:
                    per_name[name].append(paired_mmd(x, y, name == "mmd_avg", bandwidths))
            for name in names:
                if per_name[name]:
                    values[name, pair][r] = np.mean(per_name[name])
    return {name: {**_summary(values[name, "train"]),
                   "heldout": _summary(values[name, "heldout"]) if test is not None else None,
                   "real": _summary(values[name, "real"]) if test is not None else None,
                   "mmd_protocol": "authors", "per_class": per_class}
            for name in names}
