"""Objective metrics of sets of motions (seeds 000, 001, 003, 004), in plain numpy.

Inputs are arrays: ``features`` ``(N, F)`` (the action classifier's 30-d layer),
``motions`` ``(N, T, J, D)`` (or any ``(N, T, ...)``) of joint coordinates, ``labels``
``(N,)`` (action indices or names). Pairwise distances come from matrix products, never
Python loops over pairs, so thousands of motions take seconds.

- :func:`fid`, :func:`accuracy`, :func:`diversity`, :func:`multimodality`: Action2Motion
  (seed 000, Sec. 4.2.1).
- :func:`mmd`, :func:`mmd_avg`, :func:`mmd_seq`: seeds 003 (appendix) and 004 (Sec. 4.1),
  the unbiased estimate of Gretton et al. with a Gaussian kernel whose bandwidth is swept
  over 1e-4 ... 1e9, the maximum taken.
- :func:`apd`, :func:`n_apd`, :func:`mode_homogeneity`, :func:`dist_e`: ODMO (seed 001,
  Sec. 4.2.3, 4.3.1 and 4.4).
- :func:`subset_mmd` and :func:`subset_apd`: the same estimates for many subsets of one
  pool at once, from one distance matrix (what repeated evaluation needs).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg, stats

# Kernel k(x, y) = exp(-|x - y|^2 / b) for b = 10^-4 ... 10^9, as in the MMD code of
# Walker et al. that seeds 003 and 004 follow.
BANDWIDTHS = np.logspace(-4, 9, 14)
# Kernel exponents are clipped here so that exp never returns subnormal numbers, on which
# x86 arithmetic is a hundred times slower; the values lost are below 1e-38 (1e-304).
FLOAT32_EXP_FLOOR = np.float32(-87.0)
FLOAT64_EXP_FLOOR = -700.0


class MetricError(ValueError):
    """A metric was given arrays it cannot use (wrong shapes, too few motions)."""


def sq_dists(x: np.ndarray, y: np.ndarray | None = None) -> np.ndarray:
    """Return squared Euclidean distances ``(..., N, M)`` between rows of ``x`` and ``y``.

    ``x`` is ``(..., N, F)`` and ``y`` ``(..., M, F)`` (leading axes batch); without ``y``,
    the distances within ``x``, with an exact zero diagonal.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)  # strided inputs give strided, slow results
    same = y is None
    y = x if same else np.ascontiguousarray(y, dtype=np.float64)
    xx = np.einsum("...nf,...nf->...n", x, x)
    yy = xx if same else np.einsum("...mf,...mf->...m", y, y)
    dists = xx[..., :, None] + yy[..., None, :] - 2.0 * (x @ np.swapaxes(y, -1, -2))
    np.maximum(dists, 0.0, out=dists)  # rounding can make near-equal rows slightly negative
    if same:
        np.einsum("...nn->...n", dists)[...] = 0.0
    return dists


def _rows(values, name: str, min_rows: int = 1) -> np.ndarray:
    """Return ``values`` as ``(N, F)`` float64 (later axes flattened), with at least ``min_rows``."""
    values = np.asarray(values, dtype=np.float64)
    if values.ndim < 2:
        raise MetricError(f"{name} must have shape (N, ...) with one row per motion; got {values.shape}")
    if values.shape[0] < min_rows:
        raise MetricError(f"{name} needs at least {min_rows} motions; got {values.shape[0]}")
    if not np.isfinite(values).all():
        raise MetricError(f"{name} has non-finite values; drop or repair those motions")
    return values.reshape(values.shape[0], -1)


def _labels(labels, count: int, name: str) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.shape != (count,):
        raise MetricError(f"{name} must have shape ({count},), one per motion; got {labels.shape}")
    return labels


def _rng(rng) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


# Action2Motion (seed 000): features of the action classifier.

def fid_from_stats(mu1, sigma1, mu2, sigma2) -> float:
    """Return the Fréchet distance of Gaussians N(mu1, sigma1) and N(mu2, sigma2).

    ``|mu1 - mu2|^2 + tr(sigma1 + sigma2 - 2 (sigma1 sigma2)^(1/2))``; the matrix square
    root is scipy's, its real part taken (rounding leaves tiny imaginary parts).
    """
    mu1, mu2 = (np.atleast_1d(np.asarray(mu, np.float64)) for mu in (mu1, mu2))
    sigma1, sigma2 = (np.atleast_2d(np.asarray(sigma, np.float64)) for sigma in (sigma1, sigma2))
    if mu1.shape != mu2.shape or sigma1.shape != sigma2.shape or sigma1.shape != mu1.shape * 2:
        raise MetricError(
            f"means and covariances must be (F,) and (F, F) of one F; got {mu1.shape}, "
            f"{sigma1.shape}, {mu2.shape}, {sigma2.shape}"
        )
    covmean = linalg.sqrtm(sigma1 @ sigma2)
    if not np.isfinite(covmean).all():
        # Singular products (fewer motions than features): regularise, as in the FID code.
        offset = np.eye(len(mu1)) * 1e-6
        covmean = linalg.sqrtm((sigma1 + offset) @ (sigma2 + offset))
    diff = mu1 - mu2
    return float(diff @ diff + np.trace(sigma1) + np.trace(sigma2) - 2.0 * np.trace(covmean.real))


def fid(feats_a, feats_b) -> float:
    """Return the FID between two feature sets ``(N, F)`` and ``(M, F)`` (Gaussians fit to each)."""
    a, b = _rows(feats_a, "feats_a", 2), _rows(feats_b, "feats_b", 2)
    if a.shape[1] != b.shape[1]:
        raise MetricError(f"feature sets differ in width: {a.shape[1]} and {b.shape[1]}")
    return fid_from_stats(a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False))


def accuracy(predictions, labels) -> float:
    """Return the share of motions whose predicted action is their action."""
    predictions = np.asarray(predictions)
    labels = _labels(labels, len(predictions), "labels")
    if len(labels) == 0:
        raise MetricError("accuracy needs at least one motion; got none")
    return float(np.mean(predictions == labels))


def diversity(feats, n_pairs: int = 200, rng=None) -> float:
    """Return the mean feature distance of ``n_pairs`` random pairs (A2M's diversity, S_d).

    The pairs are ``rng.integers(0, N, size=(2, n_pairs))``: two subsets drawn with
    replacement, across all actions.
    """
    feats = _rows(feats, "feats", 1)
    pairs = _rng(rng).integers(0, len(feats), size=(2, n_pairs))
    return float(np.linalg.norm(feats[pairs[0]] - feats[pairs[1]], axis=1).mean())


def multimodality(feats, labels, n_pairs: int = 20, rng=None) -> float:
    """Return the mean feature distance of ``n_pairs`` random same-action pairs, averaged over actions.

    A2M's multimodality (S_l). For each action present, in sorted order, the pairs are
    ``rng.choice(members, size=(2, n_pairs))`` (with replacement).
    """
    feats = _rows(feats, "feats", 1)
    labels = _labels(labels, len(feats), "labels")
    rng = _rng(rng)
    means = []
    for label in np.unique(labels):
        pairs = rng.choice(np.flatnonzero(labels == label), size=(2, n_pairs))
        means.append(np.linalg.norm(feats[pairs[0]] - feats[pairs[1]], axis=1).mean())
    return float(np.mean(means))


# MMD (seeds 003 and 004): Gaussian kernel, unbiased estimate, maximum over bandwidths.

def mmd_per_bandwidth(d_xx, d_yy, d_xy, bandwidths=BANDWIDTHS, paired: bool = False) -> np.ndarray:
    """Return MMD_u for each bandwidth ``(B,)`` from squared distances within and across two sets.

    ``MMD_u^2 = mean_{i != j} k(x_i, x_j) + mean_{i != j} k(y_i, y_j) - 2 mean k(x_i, y_j)``
    (Gretton et al. 2012), ``k = exp(-d^2 / b)``; negative estimates count as 0 and the
    square root is returned, as the seeds report MMD, not its square. ``paired`` (sets of
    equal size, ``x_i`` paired with ``y_i``): the cross term leaves out the pairs too,
    ``mean_{i != j} k(x_i, y_j)``, Gretton's U-statistic on pairs ``(x_i, y_i)``.
    """
    m, n = d_xx.shape[0], d_yy.shape[0]
    if m < 2 or n < 2:
        raise MetricError(f"MMD needs at least 2 motions in each set; got {m} and {n}")
    if paired and m != n:
        raise MetricError(f"paired MMD needs sets of equal size; got {m} and {n}")
    values = []
    for bandwidth in np.asarray(bandwidths, dtype=np.float64):
        kxx, kyy, kxy = (np.exp(np.maximum(-d / bandwidth, FLOAT64_EXP_FLOOR)) for d in (d_xx, d_yy, d_xy))
        sxx = kxx.sum() - np.trace(kxx)
        syy = kyy.sum() - np.trace(kyy)
        sxy = kxy.sum() - (np.trace(kxy) if paired else 0.0)
        values.append(sxx / (m * (m - 1)) + syy / (n * (n - 1))
                      - 2.0 * sxy / (m * (m - 1) if paired else m * n))
    return np.sqrt(np.maximum(values, 0.0))


def mmd(x, y, bandwidths=BANDWIDTHS) -> float:
    """Return the Gaussian-kernel MMD of two sets of rows (later axes flattened), maximum over bandwidths."""
    x, y = _rows(x, "x", 2), _rows(y, "y", 2)
    if x.shape[1] != y.shape[1]:
        raise MetricError(f"sets differ in width: {x.shape[1]} and {y.shape[1]} values per row")
    return float(mmd_per_bandwidth(sq_dists(x), sq_dists(y), sq_dists(x, y), bandwidths).max())


def _sequences(real, fake, real_labels, fake_labels):
    """Return both sets as ``(N, T, F)`` and their labels (one shared label when none)."""
    real, fake = np.asarray(real, np.float64), np.asarray(fake, np.float64)
    if real.ndim < 2 or fake.ndim < 2 or real.shape[1:] != fake.shape[1:]:
        raise MetricError(
            f"real and fake must be (N, T, ...) of the same frames and joints; got "
            f"{real.shape} and {fake.shape}"
        )
    real = real.reshape(real.shape[0], real.shape[1], -1)
    fake = fake.reshape(fake.shape[0], fake.shape[1], -1)
    if (real_labels is None) != (fake_labels is None):
        raise MetricError("pass labels for both sets or for neither")
    if real_labels is None:
        return real, fake, np.zeros(len(real), int), np.zeros(len(fake), int)
    real_labels = _labels(real_labels, len(real), "real_labels")
    fake_labels = _labels(fake_labels, len(fake), "fake_labels")
    missing = sorted(set(np.unique(fake_labels)) - set(np.unique(real_labels)), key=str)
    if missing:
        raise MetricError(f"real has no motions of action {', '.join(map(str, missing))}")
    return real, fake, real_labels, fake_labels


def mmd_avg(real, fake, real_labels=None, fake_labels=None, bandwidths=BANDWIDTHS) -> float:
    """Return MMD_avg: per action, MMD of the poses frame by frame averaged over frames; mean over actions.

    ``real`` ``(N, T, ...)`` and ``fake`` ``(M, T, ...)``. The maximum over bandwidths is
    taken per action on the frame average, as in the reference code. Without labels, all
    motions are one action.
    """
    real, fake, real_labels, fake_labels = _sequences(real, fake, real_labels, fake_labels)
    per_action = []
    for label in np.unique(fake_labels):
        x, y = fake[fake_labels == label], real[real_labels == label]
        frames = [
            mmd_per_bandwidth(sq_dists(x[:, t]), sq_dists(y[:, t]), sq_dists(x[:, t], y[:, t]), bandwidths)
            for t in range(x.shape[1])
        ]
        per_action.append(np.mean(frames, axis=0).max())
    return float(np.mean(per_action))


def mmd_seq(real, fake, real_labels=None, fake_labels=None, bandwidths=BANDWIDTHS) -> float:
    """Return MMD_seq: per action, MMD of the whole (flattened) sequences; mean over actions."""
    real, fake, real_labels, fake_labels = _sequences(real, fake, real_labels, fake_labels)
    return float(np.mean([
        mmd(fake[fake_labels == label], real[real_labels == label], bandwidths)
        for label in np.unique(fake_labels)
    ]))


def subset_mmd(d_cand, d_cross, d_ref, masks, bandwidths=BANDWIDTHS) -> np.ndarray:
    """Return MMD_u ``(..., B, R)`` between R subsets of a candidate pool and a reference set.

    ``d_cand`` ``(..., P, P)`` holds the squared distances within the pool (zero
    diagonal), ``d_cross`` ``(..., P, N)`` those to the reference, ``d_ref`` ``(..., N, N)``
    those within it; leading axes (frames, say) batch. ``masks`` ``(R, P)`` are 0/1. The
    estimate of :func:`mmd_per_bandwidth` for each subset, but each kernel matrix is
    computed once and every subset, bandwidth and batch entry is summed by one matrix
    product (few large BLAS calls stay fast when other processes share the cores).

    Kernels and that product are in float32 (three times faster). For bandwidths above
    the mean squared distance, where kernels are mostly near 1, the sums are of ``k - 1``
    (``expm1``), whose constant parts cancel exactly in MMD^2, so precision holds at every
    bandwidth: MMD^2 agrees with float64 to about 1e-8 (MMD to 1e-4 near 0, far closer
    above). Subsets of fewer than 2 give NaN.
    """
    masks = np.atleast_2d(np.asarray(masks, np.float64))
    m, n = masks.sum(1), np.shape(d_ref)[-1]
    bandwidths = np.asarray(bandwidths, dtype=np.float64)
    shifted = bandwidths > float(np.mean(d_cross))
    order = np.argsort(shifted, kind="stable")  # plain kernels first, then shifted ones
    split = int(np.sum(~shifted))
    scales = (-1.0 / bandwidths[order]).astype(np.float32)[:, None, None]
    sums = []
    for d in (d_cand, d_cross, d_ref):
        kernel = np.ascontiguousarray(d, np.float32)[..., None, :, :] * scales  # (..., B, rows, cols)
        np.maximum(kernel, FLOAT32_EXP_FLOOR, out=kernel)
        np.exp(kernel[..., :split, :, :], out=kernel[..., :split, :, :])
        np.expm1(kernel[..., split:, :, :], out=kernel[..., split:, :, :])
        sums.append(kernel)
    k_cand, k_cross, k_ref = sums
    pool = k_cand.shape[-1]
    summed = (k_cand.reshape(-1, pool) @ masks.T.astype(np.float32)).astype(np.float64)
    summed = summed.reshape(k_cand.shape[:-1] + (len(masks),))  # (..., B, P, R)
    diagonal = np.where(np.arange(len(bandwidths)) < split, 1.0, 0.0)[:, None]  # k(x, x) - shift
    sxx = np.einsum("...pr,rp->...r", summed, masks) - diagonal * m
    # float32 sums are pairwise (error ~1e-7 log n); casting sums would be slower.
    sxy = k_cross.sum(-1).astype(np.float64) @ masks.T
    syy = k_ref.sum((-2, -1)).astype(np.float64)[..., None] - diagonal * n
    with np.errstate(divide="ignore", invalid="ignore"):
        values = sxx / (m * (m - 1)) + syy / (n * (n - 1)) - 2.0 * sxy / (m * n)
    values[..., m < 2] = np.nan
    if n < 2:
        values[...] = np.nan
    restored = np.empty_like(values)
    restored[..., order, :] = values  # back to the order of ``bandwidths``
    return np.sqrt(np.maximum(restored, 0.0))


# ODMO (seed 001): average pairwise distance of the sequences themselves.

def apd(motions) -> float:
    """Return the mean Euclidean distance over ordered pairs of distinct motions (flattened sequences)."""
    flat = _rows(motions, "motions", 2)
    dists = np.sqrt(sq_dists(flat))
    return float(dists.sum() / (len(flat) * (len(flat) - 1)))


def subset_apd(dists, masks) -> np.ndarray:
    """Return the APD ``(R,)`` of R subsets (0/1 masks ``(R, P)``) of a pool with distances ``(P, P)``.

    Subsets of fewer than 2 motions give NaN.
    """
    masks = np.atleast_2d(np.asarray(masks, np.float64))
    counts = masks.sum(1)
    sums = np.einsum("rp,pq,rq->r", masks, np.asarray(dists, np.float64), masks, optimize=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(counts >= 2, sums / (counts * (counts - 1)), np.nan)


def n_apd(motions, labels, real, real_labels) -> float:
    """Return n-APD: per action, APD of ``motions`` over APD of ``real``, averaged over actions, x100."""
    motions, real = _rows(motions, "motions", 2), _rows(real, "real", 2)
    labels = _labels(labels, len(motions), "labels")
    real_labels = _labels(real_labels, len(real), "real_labels")
    ratios = []
    for label in np.unique(labels):
        ours, theirs = motions[labels == label], real[real_labels == label]
        if len(ours) < 2 or len(theirs) < 2:
            raise MetricError(
                f"n-APD needs at least 2 motions of action {label} in each set; got "
                f"{len(ours)} and {len(theirs)} real"
            )
        ratios.append(apd(ours) / apd(theirs))
    return float(100.0 * np.mean(ratios))


def mode_homogeneity(motions, labels, modes) -> float:
    """Return ODMO's mode homogeneity (Sec. 4.3.1): the drop in APD when motions are grouped by mode.

    The paper measures it on real clips, grouped by the modes a model finds for their
    codes. Per action c with motions G_c split into modes G_(c,k): ``mode-APD = sum_k |G_(c,k)|
    APD(G_(c,k)) / |G_c|`` (a mode of one motion has APD 0); the result is
    ``100 * mean_c (APD(G_c) - mode-APD) / APD(G_c)``. Higher: purer modes.
    """
    motions = _rows(motions, "motions", 2)
    labels = _labels(labels, len(motions), "labels")
    modes = _labels(modes, len(motions), "modes")
    drops = []
    for label in np.unique(labels):
        members = labels == label
        if members.sum() < 2:
            raise MetricError(f"mode homogeneity needs at least 2 motions of action {label}")
        dists = np.sqrt(sq_dists(motions[members]))
        whole = dists.sum() / (len(dists) * (len(dists) - 1))
        weighted = 0.0
        for mode in np.unique(modes[members]):
            inside = modes[members] == mode
            size = int(inside.sum())
            if size > 1:
                weighted += size * dists[np.ix_(inside, inside)].sum() / (size * (size - 1))
        drops.append((whole - weighted / len(dists)) / whole)
    return float(100.0 * np.mean(drops))


def dist_e(target_end, final_root) -> float:
    """Return ODMO's goal error: mean squared distance of target and reached end points ``(N, D)``."""
    target_end = _rows(target_end, "target_end", 1)
    final_root = _rows(final_root, "final_root", 1)
    if target_end.shape != final_root.shape:
        raise MetricError(f"target_end {target_end.shape} and final_root {final_root.shape} differ")
    return float(np.mean(np.sum((target_end - final_root) ** 2, axis=1)))


def mean_ci(values, level: float = 0.95) -> tuple[float, float]:
    """Return the mean of repeated values and the half-width of its ``level`` t interval.

    ``t_{R-1} * s / sqrt(R)`` with the sample standard deviation ``s`` (``ddof = 1``) of
    the R repeats. (Action2Motion's evaluation code uses ``1.96 * std / sqrt(R)`` with the
    population deviation: for R = 5 that is 37 % narrower, for R = 20 9 %.) A single
    value has no interval (``nan``).
    """
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        raise MetricError("no repeated values to summarise")
    if values.size == 1:
        return float(values[0]), float("nan")
    quantile = stats.t.ppf(0.5 + level / 2, values.size - 1)
    return float(values.mean()), float(quantile * values.std(ddof=1) / np.sqrt(values.size))
