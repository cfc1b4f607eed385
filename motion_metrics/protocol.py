"""Repeated evaluation of a motion set against real data: mean and 95 % CI of each metric.

The protocol follows Action2Motion (seed 000: 20 repeats, 95 % interval) and reports
"Real" beside each metric, as the seeds' tables do. Two variants (:func:`run`; results
say which under ``protocol``): by default, one set of generated motions is resampled in
each repeat and Real compares held-out with training clips; Action2Motion's own (the
``a2m`` protocol of :mod:`motion_metrics.evaluate`) takes a fresh set of generated
motions per repeat (3,000 motions, 20 repeats) and its Real row compares two draws of
the held-out clips. Each repeat ``r`` draws, with a generator seeded by ``(seed, r)``:

- the generated motions, resampled with replacement within each action (a bootstrap that
  keeps the number per action); under A2M's protocol, the repeat's fresh set, whole;
- as many real test clips per action, with replacement (A2M: "real motions obtained by
  sampling with replacement from the test set") — FID's reference;
- for the Real column, a draw of test clips in the same way, compared with a draw of real
  training clips (under A2M's protocol: with another draw of test clips);
- the random pairs of diversity and multimodality.

MMD, APD, n-APD and mode homogeneity use the distinct motions of a draw (duplicates
would bias these pairwise estimates) and compare them with every real clip of the
action (seed 003: "real test sequences of action class j"). Per-action values are
averaged over the actions drawn; an action with fewer than 2 distinct motions in a
draw is left out of that repeat's average. That is the ``heldout`` MMD protocol;
:func:`paper_mmd` measures MMD_avg and MMD_seq by the ``paper`` one instead (equal,
paired draws of generated motions and training clips in standardised coordinates), and
results name which under ``mmd_protocol``.

Mode homogeneity (seed 001, Sec. 4.3.1) is measured on *real* clips grouped by the
modes a model finds in its latent space: it reads the ``modes`` of the real test clips
(one per clip, from the model that generated the motions), on each repeat's draw of
test clips, and has no Real column.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion.registry import Registry
from motion_metrics import metrics as M

METRICS = (
    "fid", "accuracy", "diversity", "multimodality", "mmd_avg", "mmd_seq", "apd", "n_apd",
    "mode_homogeneity", "dist_e",
)
# What each metric needs beyond joints and labels, and how to supply it.
NEEDS = {
    "fid": ("features", "an action classifier"),
    "accuracy": ("predictions", "an action classifier"),
    "diversity": ("features", "an action classifier"),
    "multimodality": ("features", "an action classifier"),
    "mode_homogeneity": ("modes", "the code mode of each real test clip (from the model that "
                                  "made the motions, e.g. an odmo checkpoint)"),
    "dist_e": ("end_targets", "target end points (array 'end_targets' in the motions file)"),
}
# Metrics with no Real column: targets belong to generated motions only, and mode
# homogeneity is itself measured on real clips (by the modes of a model's latent space).
GENERATED_ONLY = ("mode_homogeneity", "dist_e")
# Metrics of the real test clips, with what the model says of them (their modes).
OF_REAL_CLIPS = ("mode_homogeneity",)
LOWER_IS_BETTER = ("fid", "mmd_avg", "mmd_seq", "dist_e")


@dataclass
class MotionSet:
    """One set of motions as arrays.

    ``joints`` ``(N, T, J, D)``; ``labels`` ``(N,)`` action indices; optional
    ``features`` ``(N, F)`` and ``predictions`` ``(N,)`` of the action classifier,
    ``modes`` ``(N,)`` (of real clips: the mode of each clip's code in a model's latent
    space), ``end_targets`` and ``end_points`` ``(N, D)`` (reached end of the root,
    relative to its start).
    """

    joints: np.ndarray
    labels: np.ndarray
    features: np.ndarray | None = None
    predictions: np.ndarray | None = None
    modes: np.ndarray | None = None
    end_targets: np.ndarray | None = None
    end_points: np.ndarray | None = None

    def __post_init__(self):
        self.joints = np.asarray(self.joints, dtype=np.float64)
        self.labels = np.asarray(self.labels)
        count = len(self.joints)
        if self.joints.ndim < 3 or count == 0:
            raise M.MetricError(f"joints must be (N, T, ...) with N >= 1; got {self.joints.shape}")
        for name in ("labels", "features", "predictions", "modes", "end_targets", "end_points"):
            value = getattr(self, name)
            if value is not None and len(value) != count:
                raise M.MetricError(f"{name} has {len(value)} rows for {count} motions")

    def missing(self, metric: str) -> str | None:
        """Return what ``metric`` needs that this set lacks, or ``None``."""
        if metric == "dist_e" and (self.end_targets is None or self.end_points is None):
            return NEEDS["dist_e"][1]
        if metric in NEEDS and getattr(self, NEEDS[metric][0]) is None:
            return NEEDS[metric][1]
        return None


def check_metrics(metrics) -> list[str]:
    """Return the metric names to compute (default: all), or raise naming the unknown ones."""
    if metrics is None:
        return list(METRICS)
    metrics = [metrics] if isinstance(metrics, str) else list(metrics)
    unknown = [name for name in metrics if name not in METRICS]
    if unknown:
        raise M.MetricError(
            f"unknown metric {', '.join(map(repr, unknown))}; choose from {', '.join(METRICS)}"
        )
    return list(dict.fromkeys(metrics))


def run(generated, test: MotionSet, train: MotionSet, metrics=None, repeats: int = 20,
        seed: int = 0, diversity_pairs: int = 200, multimodality_pairs: int = 20,
        bandwidths=M.BANDWIDTHS, real_reference: str = "train") -> dict:
    """Evaluate ``generated`` against real ``test`` clips, and ``test`` against a reference (Real).

    ``generated`` is one :class:`MotionSet`, resampled with replacement in each repeat
    (the default protocol), or one fresh set per repeat used whole (Action2Motion's
    protocol: a new draw of motions from the model each time): a sequence of ``repeats``
    sets, or a function ``r -> MotionSet`` called once per repeat, in order, so that only
    one set is held at a time.
    ``real_reference`` is what the Real column compares a draw of test clips with:
    ``"train"`` (a draw of training clips) or ``"test"`` (another draw of the same test
    clips, as Action2Motion's "Real motions" row).

    Returns ``{"metrics": {name: {"mean", "ci", "std", "values", "real"}}, "skipped":
    {name: reason}, "protocol": {...}}`` where ``real`` is the same summary for the Real
    column (``None`` for metrics of generated sets only) and ``protocol`` says how the
    generated motions and the Real column were drawn.
    """
    metrics = check_metrics(metrics)
    if int(repeats) != repeats or repeats < 1:
        raise M.MetricError(f"repeats must be a positive integer; got {repeats!r}")
    if real_reference not in ("train", "test"):
        raise M.MetricError(f"real_reference must be 'train' or 'test'; got {real_reference!r}")
    fresh = not isinstance(generated, MotionSet)
    if fresh:
        if callable(generated):
            fresh_set = generated
        else:
            listed = list(generated)
            if len(listed) != repeats:
                raise M.MetricError(f"fresh generated motions need one MotionSet per repeat: "
                                    f"{repeats} repeats, got {len(listed)}")
            fresh_set = listed.__getitem__
    reference = test if real_reference == "test" else train
    first = fresh_set(0) if fresh else generated
    if not isinstance(first, MotionSet):
        raise M.MetricError(f"generated motions must be a MotionSet; got {type(first).__name__}")

    def lacking(name):
        return (test if name in OF_REAL_CLIPS else first).missing(name)

    skipped = {name: f"needs {lacking(name)}" for name in metrics if lacking(name)}
    metrics = [name for name in metrics if name not in skipped]
    _check_real(first, test, train, metrics)

    values = {name: np.empty(repeats) for name in metrics}
    real_values = {name: np.empty(repeats) for name in metrics if name not in GENERATED_ONLY}
    pairwise = [name for name in metrics if name not in _POINTWISE and name not in OF_REAL_CLIPS]
    draws = []
    for r in range(repeats):
        # A fresh set is made, measured and dropped one repeat at a time (A2M: 3,000 motions each).
        candidate = generated if not fresh else first if r == 0 else fresh_set(r)
        if fresh and r:
            if not isinstance(candidate, MotionSet):
                raise M.MetricError(f"fresh set {r} is a {type(candidate).__name__}, not a MotionSet")
            _check_real(candidate, test, train, metrics)
        draw = _draw(candidate, test, reference, np.random.default_rng([seed, r]), resample=not fresh)
        draws.append(draw)
        rng = np.random.default_rng([seed, r, 1])
        for name in metrics:
            if name in _POINTWISE:
                values[name][r] = _POINTWISE[name](candidate, draw["gen"], test, draw["ref"], rng,
                                                   diversity_pairs, multimodality_pairs)
                if name in real_values:
                    real_values[name][r] = _POINTWISE[name](
                        test, draw["real"], reference, draw["real_ref"], rng, diversity_pairs,
                        multimodality_pairs,
                    )
        if fresh and pairwise:  # the repeat's own set, all of it
            for name, row in _pairwise(candidate, test, [draw["gen"]], pairwise, bandwidths).items():
                values[name][r] = row[0]
    of_real = [name for name in metrics if name in OF_REAL_CLIPS]
    if of_real:
        values.update(_pairwise(test, train, [draw["ref"] for draw in draws], of_real, bandwidths))
    if pairwise:
        if not fresh:
            values.update(_pairwise(generated, test, [draw["gen"] for draw in draws], pairwise,
                                    bandwidths))
        real_names = [name for name in pairwise if name in real_values]
        real_values.update(_pairwise(test, reference, [draw["real"] for draw in draws], real_names,
                                     bandwidths))
    return {
        "metrics": {
            name: {**_summary(values[name]),
                   "real": _summary(real_values[name]) if name in real_values else None}
            for name in metrics
        },
        "skipped": skipped,
        "protocol": {
            "generated": "a fresh set per repeat" if fresh else "resampled with replacement per repeat",
            "real": ("held-out clips against another draw of the held-out clips" if real_reference == "test"
                     else "held-out clips against training clips"),
        },
    }


def _check_real(generated: MotionSet, test: MotionSet, train: MotionSet, metrics) -> None:
    """Raise unless the real test and training clips have every action and input the metrics need."""
    actions = np.unique(generated.labels)
    for name, real_set in (("test", test), ("train", train)):
        absent = [str(a) for a in actions if not np.any(real_set.labels == a)]
        if absent:
            raise M.MetricError(
                f"the real {name} clips have no motions of action {', '.join(absent)}; "
                f"evaluate actions the real data has"
            )
        for metric in metrics:
            if metric not in GENERATED_ONLY and real_set.missing(metric):
                raise M.MetricError(f"real {name} clips lack what {metric} needs: {real_set.missing(metric)}")


def _summary(values: np.ndarray) -> dict:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return {"mean": None, "ci": None, "std": None, "values": [None] * len(values)}
    mean, ci = M.mean_ci(finite)  # a t interval over the repeats (none of one repeat)
    return {"mean": mean, "ci": ci if np.isfinite(ci) else None, "std": float(finite.std()),
            "values": [float(v) if np.isfinite(v) else None for v in values]}


def _stratified(rng, pool_labels, counts: dict) -> np.ndarray:
    """Return indices into ``pool_labels``: ``counts[a]`` per action ``a``, with replacement."""
    return np.concatenate([
        rng.choice(np.flatnonzero(pool_labels == action), size=count)
        for action, count in counts.items()
    ])


def _draw(generated, test, reference, rng, resample: bool = True) -> dict:
    """Return one repeat's indices: generated, its real reference, Real candidate and reference.

    Without ``resample``, the generated motions are all taken once, in order.
    """
    actions, sizes = np.unique(generated.labels, return_counts=True)
    counts = dict(zip(actions, sizes))
    gen = (_stratified(rng, generated.labels, counts) if resample
           else np.concatenate([np.flatnonzero(generated.labels == action) for action in actions]))
    return {
        "gen": gen,
        "ref": _stratified(rng, test.labels, counts),
        "real": _stratified(rng, test.labels, counts),
        "real_ref": _stratified(rng, reference.labels, counts),
    }


def _fid(cand, idx, ref, ref_idx, rng, *_):
    return M.fid(cand.features[idx], ref.features[ref_idx])


def _accuracy(cand, idx, *_):
    return M.accuracy(cand.predictions[idx], cand.labels[idx])


def _diversity(cand, idx, ref, ref_idx, rng, diversity_pairs, _):
    return M.diversity(cand.features[idx], diversity_pairs, rng)


def _multimodality(cand, idx, ref, ref_idx, rng, _, multimodality_pairs):
    return M.multimodality(cand.features[idx], cand.labels[idx], multimodality_pairs, rng)


def _dist_e(cand, idx, *_):
    return M.dist_e(cand.end_targets[idx], cand.end_points[idx])


# Metrics computed on each repeat's draw directly (cheap: features or one value per motion).
_POINTWISE = {
    "fid": _fid, "accuracy": _accuracy, "diversity": _diversity,
    "multimodality": _multimodality, "dist_e": _dist_e,
}


# Kernel values held at once when MMD_avg batches frames (float32: 4 bytes each).
KERNEL_BUDGET = 8_000_000


def _pairwise(cand: MotionSet, ref: MotionSet, draws: list[np.ndarray], names: list[str],
              bandwidths) -> dict[str, np.ndarray]:
    """Return per-repeat values ``(R,)`` of the pairwise metrics, action by action.

    For each action, squared distances within the candidate motions, to the reference
    clips and within those are computed once (per frame for MMD_avg, in batches of
    frames); each repeat's distinct draw is a 0/1 mask over the candidates.
    """
    if not names:
        return {}
    per_action = {name: [] for name in names}
    for action in np.unique(cand.labels):
        members = np.flatnonzero(cand.labels == action)
        pool = cand.joints[members]
        both = np.concatenate([pool, ref.joints[ref.labels == action]])
        both = both.reshape(len(both), both.shape[1], -1)  # (P + N, T, J * D)
        size = len(members)
        masks = np.zeros((len(draws), size))
        for r, drawn in enumerate(draws):
            masks[r, np.searchsorted(members, np.intersect1d(drawn, members))] = 1.0
        if "mmd_avg" in names:
            per_frame = len(bandwidths) * len(both) ** 2
            chunk = max(1, KERNEL_BUDGET // per_frame)
            frames = both.shape[1]
            frame_mmd = 0.0
            for start in range(0, frames, chunk):
                d = M.sq_dists(both[:, start:start + chunk].transpose(1, 0, 2))  # (t, P + N, P + N)
                blocks = d[:, :size, :size], d[:, :size, size:], d[:, size:, size:]
                frame_mmd = frame_mmd + M.subset_mmd(*blocks, masks, bandwidths).sum(0)
            per_action["mmd_avg"].append(np.max(frame_mmd / frames, axis=0))
        d_seq = M.sq_dists(both.reshape(len(both), -1))
        d_cand, d_cross, d_ref = d_seq[:size, :size], d_seq[:size, size:], d_seq[size:, size:]
        if "mmd_seq" in names:
            values = M.subset_mmd(d_cand, d_cross, d_ref, masks, bandwidths)
            per_action["mmd_seq"].append(np.max(values, axis=0))
        dists = np.sqrt(d_cand)
        apd = M.subset_apd(dists, masks)
        if "apd" in names:
            per_action["apd"].append(apd)
        if "n_apd" in names:
            real_apd = M.subset_apd(np.sqrt(d_ref), np.ones(len(d_ref)))[0]
            per_action["n_apd"].append(100.0 * apd / real_apd)
        if "mode_homogeneity" in names:
            per_action["mode_homogeneity"].append(_mode_drop(dists, masks, apd, cand.modes[members]))
    with np.errstate(invalid="ignore"):
        return {name: _nanmean(np.stack(rows)) for name, rows in per_action.items()}


def _mode_drop(dists, masks, apd, modes) -> np.ndarray:
    """Return ``100 * (APD - mode-APD) / APD`` per repeat for one action (see :func:`M.mode_homogeneity`)."""
    weighted = np.zeros(len(masks))
    for mode in np.unique(modes):
        mode_masks = masks * (modes == mode)
        mode_apd = np.nan_to_num(M.subset_apd(dists, mode_masks))  # a mode of one: APD 0
        weighted += mode_masks.sum(1) * mode_apd
    return 100.0 * (apd - weighted / masks.sum(1)) / apd


def _nanmean(rows: np.ndarray) -> np.ndarray:
    """Return the mean over actions (axis 0), ignoring NaN; all-NaN columns stay NaN."""
    valid = np.isfinite(rows)
    counts = valid.sum(0)
    sums = np.where(valid, rows, 0.0).sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)


# MMD protocols: ``heldout`` is :func:`run`'s (distinct drawn motions against every
# held-out clip of the action, raw coordinates); ``paper`` is :func:`paper_mmd`'s;
# ``authors`` is :func:`motion_metrics.authors_mmd.authors_mmd`'s.
MMD_PROTOCOLS = Registry("MMD protocol")
for _name, _description in {
    "heldout": "distinct drawn motions against every held-out clip of the action, raw coordinates",
    "paper": "per action, equal numbers of generated motions and training clips drawn without "
             "replacement in each repeat and paired, coordinates standardised by the training clips",
    "authors": "SA-GCN's code: poses centred on the hip in every frame, scaled by depth (estimated "
               "from the figure's size), standardised by the training clips; per class 100 "
               "generated motions paired with 100 training clips (the authors' number) and with "
               "held-out clips, drawn afresh in each repeat",
}.items():
    MMD_PROTOCOLS.add(_name, _description)


def paper_mmd(generated: MotionSet, train: MotionSet, test: MotionSet | None,
              metrics=("mmd_avg", "mmd_seq"),
              repeats: int = 20, seed: int = 0, bandwidths=M.BANDWIDTHS) -> dict:
    """Return MMD_avg / MMD_seq summaries (with Real, given held-out clips) by the ``paper`` protocol.

    Each repeat ``r`` (generator seeded by ``(seed, r, 2)``), for each action of the
    generated motions, draws ``n`` generated motions and ``n`` training clips without
    replacement, ``n`` the smaller of the two counts, so both sides of every MMD have the
    same size, and pairs the ``i``-th of each (the estimate leaves out the pairs' cross
    terms, as SA-GCN's released evaluation does); every coordinate is standardised by the
    mean and standard deviation of the training clips (over clips and frames), as its
    data are. Seed 003's appendix calls the real side "real test sequences", while
    SA-GCN's evaluation draws them from its training set: this is the latter. The Real column compares ``n`` held-out clips
    with ``n`` training clips drawn the same way (``n`` the smallest of the three counts);
    without ``test`` there is no Real column (``real`` is ``None``), as when the score
    selects a checkpoint. Returns ``{name: {"mean", "ci", "std", "values", "real",
    "mmd_protocol"}}``.
    """
    names = [name for name in check_metrics(list(metrics)) if name in ("mmd_avg", "mmd_seq")]
    if int(repeats) != repeats or repeats < 1:
        raise M.MetricError(f"repeats must be a positive integer; got {repeats!r}")
    flat = train.joints.reshape(-1, int(np.prod(train.joints.shape[2:])))
    mean, std = flat.mean(0), flat.std(0)
    std = np.maximum(std, 1e-6 * max(float(std.max()), 1e-12))  # constant coordinates: no 1/0

    def normalised(motions: MotionSet) -> np.ndarray:
        joints = motions.joints.reshape(len(motions.joints), motions.joints.shape[1], -1)
        if joints.shape[1:] != (train.joints.shape[1], flat.shape[1]):
            raise M.MetricError(f"motions of shape {motions.joints.shape} do not match the training "
                                f"clips' {train.joints.shape}; use clips of the same length and skeleton")
        return (joints - mean) / std

    gen, ref = normalised(generated), normalised(train)
    real = None if test is None else normalised(test)
    actions = np.unique(generated.labels)
    sides = [("training", train.labels)] + ([] if test is None else [("held-out", test.labels)])
    for name, labels in sides:
        absent = [str(a) for a in actions if np.sum(labels == a) < 2]
        if absent:
            raise M.MetricError(f"the {name} clips have fewer than 2 motions of action "
                                f"{', '.join(absent)}; MMD needs at least 2 on each side")
    def paired_mmd(name, x, y):  # x, y (n, T, F) paired row by row
        if name == "mmd_seq":
            x, y = x.reshape(len(x), 1, -1), y.reshape(len(y), 1, -1)
        per_frame = [M.mmd_per_bandwidth(M.sq_dists(x[:, t]), M.sq_dists(y[:, t]),
                                         M.sq_dists(x[:, t], y[:, t]), bandwidths, paired=True)
                     for t in range(x.shape[1])]
        return float(np.mean(per_frame, axis=0).max())

    values = {name: np.full(repeats, np.nan) for name in names}
    real_values = {name: np.full(repeats, np.nan) for name in names}
    for r in range(repeats):
        rng = np.random.default_rng([seed, r, 2])
        picks = {"gen": [], "gen_ref": [], "real": [], "real_ref": []}
        for action in actions:
            pools = {key: np.flatnonzero(labels == action) for key, labels in
                     (("gen", generated.labels), ("train", train.labels))}
            n = min(len(pools["gen"]), len(pools["train"]))
            if n >= 2:
                picks["gen"].append(rng.choice(pools["gen"], n, replace=False))
                picks["gen_ref"].append(rng.choice(pools["train"], n, replace=False))
            if test is None:
                continue
            pools["test"] = np.flatnonzero(test.labels == action)
            n = min(n, len(pools["test"]))
            if n >= 2:
                picks["real"].append(rng.choice(pools["test"], n, replace=False))
                picks["real_ref"].append(rng.choice(pools["train"], n, replace=False))
        for out, cand, key in ((values, gen, "gen"), (real_values, real, "real")):
            if not picks[key]:
                continue
            for name in names:
                out[name][r] = np.mean([paired_mmd(name, cand[idx], ref[ref_idx])
                                        for idx, ref_idx in zip(picks[key], picks[key + "_ref"])])
    return {name: {**_summary(values[name]),
                   "real": None if test is None else _summary(real_values[name]),
                   "mmd_protocol": "paper"} for name in names}
