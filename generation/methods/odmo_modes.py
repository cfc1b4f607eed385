"""Modes of a code space: Gaussian mixtures by EM, silhouette scores, ODMO's choice of K.

ODMO (seed 001, Sec. 3.3 and supplement 2.2) fits one Gaussian mixture per action to
the codes of the real clips, picks the number of components by the silhouette score
(k = 3...11: the first i with ``S_i > 0.95 S_{i+1}``) and drops components of fewer
than 10 clips. Everything here is numpy; a mixture is a dict of arrays (``weights``
``(K,)``, ``means`` ``(K, D)``, ``covariances`` ``(K, D, D)``, ``sizes`` ``(K,)``),
so it saves in a checkpoint's ``extras`` as it is.
"""

from __future__ import annotations

import numpy as np

# Silhouette scores use at most this many codes (its cost is quadratic).
SILHOUETTE_SAMPLE = 2000
_LOG_2PI = np.log(2 * np.pi)


def log_gaussian(x: np.ndarray, means: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """Return log densities ``(N, K)`` of points ``(N, D)`` under full Gaussians ``(K, D[, D])``."""
    out = np.empty((len(x), len(means)))
    for k, (mean, cov) in enumerate(zip(means, covariances)):
        chol = np.linalg.cholesky(cov)
        solved = np.linalg.solve(chol, (x - mean).T)
        logdet = 2 * np.log(np.diag(chol)).sum()
        out[:, k] = -0.5 * ((solved**2).sum(0) + logdet + x.shape[1] * _LOG_2PI)
    return out


def _logsumexp(a: np.ndarray) -> np.ndarray:
    top = a.max(axis=1, keepdims=True)
    return (top + np.log(np.exp(a - top).sum(axis=1, keepdims=True)))[:, 0]


def _kmeans_labels(x: np.ndarray, k: int, rng: np.random.Generator, iters: int = 20) -> np.ndarray:
    """Return k-means labels of ``x`` from k-means++ seeds (EM's initial responsibilities)."""
    centres = [x[rng.integers(len(x))]]
    for _ in range(1, k):
        d2 = ((x[:, None] - np.array(centres)[None]) ** 2).sum(-1).min(axis=1)
        total = d2.sum()
        pick = rng.choice(len(x), p=d2 / total) if total > 0 else rng.integers(len(x))
        centres.append(x[pick])
    centres = np.array(centres)
    labels = np.zeros(len(x), dtype=int)
    for _ in range(iters):
        labels = ((x[:, None] - centres[None]) ** 2).sum(-1).argmin(axis=1)
        for j in range(k):
            if (labels == j).any():
                centres[j] = x[labels == j].mean(axis=0)
    return labels


def _m_step(x: np.ndarray, resp: np.ndarray, reg: float):
    counts = resp.sum(axis=0) + 10 * np.finfo(float).eps
    means = resp.T @ x / counts[:, None]
    covariances = np.empty((resp.shape[1], x.shape[1], x.shape[1]))
    for k in range(resp.shape[1]):
        centred = x - means[k]
        covariances[k] = (resp[:, k, None] * centred).T @ centred / counts[k]
        covariances[k].flat[:: x.shape[1] + 1] += reg
    return counts / len(x), means, covariances


def fit_gmm(x: np.ndarray, k: int, rng: np.random.Generator, restarts: int = 1,
            iters: int = 100, tol: float = 1e-4, reg: float = 1e-6) -> tuple[dict, np.ndarray]:
    """Fit a ``k``-component full-covariance Gaussian mixture to ``x`` ``(N, D)`` by EM.

    Each restart starts from k-means; the one of highest likelihood wins. Return the
    mixture (``weights``, ``means``, ``covariances``) and the hard labels ``(N,)``.
    """
    x = np.asarray(x, dtype=np.float64)
    best, best_score = None, -np.inf
    for _ in range(max(1, restarts)):
        resp = np.eye(k)[_kmeans_labels(x, k, rng)]
        previous = -np.inf
        for _ in range(iters):
            weights, means, covariances = _m_step(x, resp, reg)
            joint = log_gaussian(x, means, covariances) + np.log(weights)
            norm = _logsumexp(joint)
            resp = np.exp(joint - norm[:, None])
            score = norm.mean()
            if abs(score - previous) < tol:
                break
            previous = score
        if score > best_score:
            best, best_score = (weights, means, covariances, resp), score
    weights, means, covariances, resp = best
    return {"weights": weights, "means": means, "covariances": covariances}, resp.argmax(axis=1)


def silhouette(x: np.ndarray, labels: np.ndarray, rng: np.random.Generator | None = None) -> float:
    """Return the mean silhouette coefficient (Rousseeuw 1987) of a labelling, in ``[-1, 1]``.

    A point alone in its cluster scores 0. Fewer than two clusters score 0. Above
    :data:`SILHOUETTE_SAMPLE` points, a random subset (from ``rng``) is scored.
    """
    x, labels = np.asarray(x, dtype=np.float64), np.asarray(labels)
    if len(x) > SILHOUETTE_SAMPLE:
        keep = (rng or np.random.default_rng(0)).choice(len(x), SILHOUETTE_SAMPLE, replace=False)
        x, labels = x[keep], labels[keep]
    names, labels = np.unique(labels, return_inverse=True)
    if len(names) < 2:
        return 0.0
    squared = (x**2).sum(1)
    distance = np.sqrt(np.maximum(squared[:, None] + squared[None] - 2 * x @ x.T, 0.0))
    members = np.eye(len(names))[labels]  # (N, K)
    sizes = members.sum(0)
    sums = distance @ members  # total distance of each point to each cluster
    own = sizes[labels] - 1
    a = sums[np.arange(len(x)), labels] / np.maximum(own, 1)
    other = sums / sizes
    other[np.arange(len(x)), labels] = np.inf
    b = other.min(axis=1)
    scores = np.where(own > 0, (b - a) / np.maximum(np.maximum(a, b), 1e-300), 0.0)
    return float(scores.mean())


def choose_components(scores: dict[int, float], ratio: float = 0.95) -> int:
    """Return ODMO's K: the first ``i`` with ``S_i > ratio * S_{i+1}``, else the largest ``i``."""
    ks = sorted(scores)
    for i, j in zip(ks, ks[1:]):
        if scores[i] > ratio * scores[j]:
            return i
    return ks[-1]


def discover_modes(x: np.ndarray, rng: np.random.Generator, k_min: int = 3, k_max: int = 11,
                   ratio: float = 0.95, min_size: int = 10, restarts: int = 1,
                   reg: float = 1e-6) -> dict:
    """Return the modes of codes ``x`` ``(N, D)``: a mixture sorted by size, largest first.

    K is chosen by silhouette among ``k_min...k_max`` (only values below N can be
    scored; with fewer codes one Gaussian is fitted). Components of fewer than
    ``min_size`` members are dropped, but the largest always stays; weights are the
    kept members' shares. Adds ``sizes`` (members per mode), ``k`` (components fitted)
    and ``silhouette`` (``(k, S_k)`` rows).
    """
    x = np.asarray(x, dtype=np.float64)
    candidates = list(range(k_min, min(k_max, len(x) - 1) + 1))
    fits, scores = {}, {}
    for k in candidates:
        fits[k] = fit_gmm(x, k, rng, restarts=restarts, reg=reg)
        scores[k] = silhouette(x, fits[k][1], rng)
    k = choose_components(scores, ratio) if scores else 1
    mixture, labels = fits[k] if k in fits else fit_gmm(x, 1, rng, reg=reg)
    sizes = np.bincount(labels, minlength=k)
    order = [j for j in np.argsort(-sizes, kind="stable") if sizes[j] >= min_size]
    order = order or [int(np.argmax(sizes))]
    kept = sizes[order]
    return {
        "weights": kept / kept.sum(),
        "means": mixture["means"][order],
        "covariances": mixture["covariances"][order],
        "sizes": kept.astype(np.int64),
        "k": int(k),
        "silhouette": np.array([[c, scores[c]] for c in candidates]).reshape(-1, 2),
    }


def single_gaussian(x: np.ndarray, reg: float = 1e-6) -> dict:
    """Return one Gaussian fitted to codes ``x`` ``(N, D)``, in the layout of :func:`discover_modes`."""
    x = np.asarray(x, dtype=np.float64)
    mixture, _ = fit_gmm(x, 1, np.random.default_rng(0), reg=reg)
    return {**mixture, "sizes": np.array([len(x)], dtype=np.int64), "k": 1,
            "silhouette": np.zeros((0, 2))}


def gaussian_draws(means: np.ndarray, covariances: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Return ``mean + L noise`` row by row, ``L`` the Cholesky factor of each covariance.

    ``means`` ``(N, D)``, ``covariances`` ``(N, D, D)``, standard normal ``noise`` ``(N, D)``;
    the same noise through two Gaussians gives corresponding draws of both.
    """
    chol = np.linalg.cholesky(covariances)
    return means + np.einsum("nij,nj->ni", chol, noise)


def nearest(queries: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Return the index of the nearest row of ``points`` for each row of ``queries``."""
    d2 = (queries**2).sum(1)[:, None] + (points**2).sum(1)[None] - 2 * queries @ points.T
    return d2.argmin(axis=1)
