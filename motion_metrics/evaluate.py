"""Evaluate a set of motions against a dataset's real clips: what ``manage.py evaluate`` runs.

This module checks that the motions fit the dataset and the classifier, turns motions
into arrays (classifier features and predictions included) and hands them to the
repeat/CI protocol of :mod:`motion_metrics.protocol`, which works on numpy arrays only.
:func:`evaluate` takes one set of motions (the ``bootstrap`` protocol);
:func:`evaluate_model` samples a fresh set from a model per repeat (``a2m``, Action2Motion's
protocol). Results name theirs under ``protocol``.

Real clips are the dataset's clips of the motions' length and frame rate, divided as the
classifier was trained (held-out subjects or takes; without a classifier, the default
split of :func:`motion_metrics.recognition.make_split`): generated motions are compared with
the held-out ("test") clips, and the Real column compares those with the training clips.
Before the metrics on joints (MMD, APD), every motion is moved so that its root starts
above the origin (height kept), as the methods place their samples.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from motion.datasets import Dataset, get_dataset
from motion.motion import Motion
from motion.registry import Registry
from motion_metrics.recognition import ActionClassifier, ClassifierError, make_split
from motion.skeletons import get_skeleton
from motion_metrics import protocol
from motion_metrics.metrics import BANDWIDTHS, MetricError

METRICS = protocol.METRICS
LOWER_IS_BETTER = protocol.LOWER_IS_BETTER


# Optional arrays of an interchange file that some metrics need, one entry per motion
# (``modes`` are read back for the record; mode homogeneity groups real clips instead).
EXTRAS = ("modes", "end_targets")


class EvaluationError(ValueError):
    """Motions cannot be evaluated as asked (other skeleton, length, dataset or actions)."""


def read_extras(path: str | Path) -> dict[str, np.ndarray]:
    """Return the optional per-motion arrays of an interchange ``.npz`` (``modes``, ``end_targets``)."""
    with np.load(path, allow_pickle=False) as data:
        return {key: data[key] for key in EXTRAS if key in data.files}


# How the generated motions and the Real column are drawn in each repeat.
PROTOCOLS = Registry("repeat protocol")
PROTOCOLS.add("bootstrap",
              "one set of motions resampled per repeat; Real: held-out vs training clips")
PROTOCOLS.add("a2m", "Action2Motion's: a fresh set of motions per repeat (3,000, 20 repeats); "
                     "Real: two draws of the held-out clips")


def evaluate(dataset: Dataset | str, motions: Sequence[Motion], classifier: ActionClassifier | None = None,
             metrics: Sequence[str] | None = None, repeats: int = 20, seed: int = 0, *,
             real_modes=None, end_targets=None, data_root=None, diversity_pairs: int = 200,
             multimodality_pairs: int = 20, bandwidths=BANDWIDTHS,
             mmd_protocol: str = "heldout", split=None, real_reference: str = "train") -> dict:
    """Return every metric's mean, 95 % CI and per-repeat values, with the Real values beside.

    The ``bootstrap`` protocol: ``motions`` are resampled in each repeat, and Real compares
    held-out with training clips. ``motions`` share one skeleton (the dataset's), length
    and frame rate. ``real_modes`` maps a list of real clips to their modes ``(N,)`` in
    the latent space of the model that made the motions (e.g. ``ODMO.clip_modes``): with
    it, mode homogeneity is measured on the real test clips grouped by those modes (seed
    001, Sec. 4.3.1). ``end_targets`` ``(N, D)`` (the root end point each motion was asked
    to reach, relative to its start) enable dist_e. Metrics needing what is absent (a
    classifier, modes, targets) are listed under ``skipped`` with the reason.
    ``mmd_protocol`` is how MMD_avg and MMD_seq are measured (``MMD_PROTOCOLS``):
    ``heldout`` (the default, the protocol's draws against the held-out clips) or
    ``paper`` (:func:`motion_metrics.protocol.paper_mmd`: against the training clips,
    standardised, equal counts); the result names it under ``mmd_protocol``. ``split``
    (a :class:`motion_metrics.recognition.Split`) says which real clips are held out when no
    classifier brings its own. ``real_reference`` ``test`` makes the Real column Action2Motion's
    (two draws of the held-out clips) instead of held-out against training clips.
    """
    return _evaluate(dataset, list(motions), classifier, metrics, repeats, seed, "bootstrap",
                     real_modes=real_modes, end_targets=end_targets, data_root=data_root,
                     diversity_pairs=diversity_pairs, multimodality_pairs=multimodality_pairs,
                     bandwidths=bandwidths, mmd_protocol=mmd_protocol, split=split,
                     real_reference=real_reference)


def evaluate_model(dataset: Dataset | str, model, classifier: ActionClassifier | None = None,
                   metrics: Sequence[str] | None = None, repeats: int = 20, seed: int = 0, *,
                   n: int = 3000, frames: int | None = None, actions: Sequence[str] | None = None,
                   real_modes=None, data_root=None, diversity_pairs: int = 200,
                   multimodality_pairs: int = 20, bandwidths=BANDWIDTHS) -> dict:
    """Evaluate a model by Action2Motion's protocol (``a2m``): ``n`` fresh motions per repeat.

    Each repeat ``r`` samples ``n`` motions from ``model`` (spread evenly over
    ``actions``, default: the model's actions the dataset has; seed ``(seed, r)``) and
    uses them whole; the Real column compares two draws of the held-out clips (A2M: 3,000
    motions, 20 repeats). Otherwise as :func:`evaluate`.
    """
    data = get_dataset(dataset, data_root) if isinstance(dataset, str) else dataset
    if int(n) != n or n < 1:
        raise EvaluationError(f"n must be a positive number of motions per repeat; got {n!r}")
    known = set(data.actions())
    actions = [a for a in model.actions if a in known] if actions is None else list(actions)
    if not actions:
        raise EvaluationError(f"the model's actions ({', '.join(model.actions)}) are not actions of "
                              f"dataset {data.name!r}; evaluate it against the dataset it imitates")
    if n < len(actions):
        raise EvaluationError(f"n = {n} motions per repeat cannot cover {len(actions)} actions; "
                              f"give at least {len(actions)}")
    labels = [actions[i * len(actions) // n] for i in range(n)]  # n // C or n // C + 1 each

    def sample(r):
        try:
            return model.sample(labels, frames, seed=int(seed) * 1_000_003 + r)
        except ValueError as exc:  # MethodError: actions or options the model cannot take
            raise EvaluationError(f"cannot sample from the model: {exc}") from None

    result = _evaluate(data, sample(0), classifier, metrics, repeats, seed, "a2m", more=sample,
                       real_modes=real_modes, end_targets=None, data_root=data_root,
                       diversity_pairs=diversity_pairs, multimodality_pairs=multimodality_pairs,
                       bandwidths=bandwidths)
    result["method"] = getattr(model, "name", None)
    return result


def training_mmd(motions: Sequence[Motion], train_clips: Sequence[Motion], metric: str = "mmd_seq",
                 repeats: int = 5, seed: int = 0, bandwidths=BANDWIDTHS,
                 mmd_protocol: str = "paper") -> float:
    """Return ``metric`` (MMD_seq or MMD_avg) of ``motions`` against ``train_clips``.

    The mean over ``repeats`` of the ``paper`` (:func:`motion_metrics.protocol.paper_mmd`)
    or ``authors`` protocol's score against the training clips, with no Real column: the
    score by which ``compare_methods --select best-mmd-seq`` chooses a checkpoint, as
    seeds 003/004 chose theirs. Motions and clips (of the motions' actions) are moved as
    for :func:`evaluate`; both must have the same length.
    """
    if mmd_protocol not in ("paper", "authors"):
        raise EvaluationError(f"checkpoints are scored by the paper or authors MMD protocol, not "
                              f"{mmd_protocol!r}")
    motions = list(motions)
    if not motions:
        raise EvaluationError("no motions to score")
    index = {name: i for i, name in enumerate(sorted({m.action for m in motions}))}
    clips = [clip for clip in train_clips if clip.action in index]
    if not clips:
        raise EvaluationError(f"no training clips of {', '.join(index)} to score the motions against")
    try:
        scores = _own_mmd(mmd_protocol, motions[0].skeleton,
                          _motion_set(motions, index, None, "generated"),
                          _motion_set(clips, index, None, "train"), None, [metric], repeats, seed,
                          bandwidths)
    except MetricError as exc:
        raise EvaluationError(str(exc)) from None
    if metric not in scores or scores[metric]["mean"] is None:
        raise EvaluationError(f"{metric!r} is not an MMD of the paper protocol (mmd_seq, mmd_avg), or "
                              f"no action has 2 motions to measure it on")
    return scores[metric]["mean"]


def _evaluate(dataset, motions: list[Motion], classifier, metrics, repeats, seed, protocol_name,
              *, more=None, real_modes, end_targets, data_root, diversity_pairs, multimodality_pairs,
              bandwidths, mmd_protocol="heldout", split=None, real_reference=None) -> dict:
    """Evaluate one set of motions (``bootstrap``), or ``motions`` then ``more(r)`` per repeat ``r``."""
    if mmd_protocol not in protocol.MMD_PROTOCOLS:
        raise EvaluationError(f"unknown MMD protocol {mmd_protocol!r}; choose one of: "
                              f"{', '.join(sorted(protocol.MMD_PROTOCOLS))}")
    if mmd_protocol in ("paper", "authors") and more is not None:
        raise EvaluationError(f"the {mmd_protocol} MMD protocol measures one set of motions; "
                              f"use it with the bootstrap protocol (--motions), not a2m")
    data = get_dataset(dataset, data_root) if isinstance(dataset, str) else dataset
    try:
        metrics = protocol.check_metrics(metrics)
    except MetricError as exc:
        raise EvaluationError(str(exc)) from None
    frames, fps = _check_motions(data, motions)
    actions = sorted({m.action for m in motions})
    if classifier is not None:
        _check_classifier(data, classifier, frames, fps, actions)
        names = classifier.actions
    else:
        names = data.actions()
    clips = data.clips(frames=frames, fps=fps, actions=actions)
    if classifier is not None and classifier.split:
        split = classifier.split
    elif split is None:
        split = make_split(data, clips)
    train, test = split.divide(clips)
    index = {name: i for i, name in enumerate(names)}
    sets = {}
    for key, group in (("generated", motions), ("test", test), ("train", train)):
        if not group:
            raise EvaluationError(
                f"dataset {data.name!r} has no real {key} clips of {frames} frames at {fps:g} fps "
                f"for {', '.join(actions)} ({split.describe()}); check --data-root and the motions' length"
            )
        sets[key] = _motion_set(group, index, classifier, key)
    sets["generated"].end_targets = _optional(end_targets, len(motions), "end_targets")
    if real_modes is not None and "mode_homogeneity" in metrics:
        try:
            found = real_modes(test)
        except ValueError as exc:  # MethodError: clips the model cannot encode
            raise EvaluationError(f"cannot find the modes of the real test clips: {exc}") from None
        sets["test"].modes = _optional(found, len(test), "modes of the real test clips")
    generated = sets["generated"]
    if more is not None:
        def fresh(r):
            if r == 0:
                return sets["generated"]
            group = more(r)
            if _check_motions(data, group) != (frames, fps):
                raise EvaluationError(f"repeat {r}'s motions differ in length or frame rate from the first")
            return _motion_set(group, index, classifier, "generated")
        generated = fresh
    # The paper protocol measures MMD itself: the repeats' draws leave it out (MMD_avg
    # against every held-out clip is the slowest of their metrics).
    paper = [name for name in metrics if mmd_protocol in ("paper", "authors")
             and name in ("mmd_avg", "mmd_seq")]
    try:
        result = protocol.run(generated, sets["test"], sets["train"],
                              [name for name in metrics if name not in paper], repeats, seed,
                              diversity_pairs, multimodality_pairs, bandwidths,
                              real_reference=real_reference or ("test" if more is not None
                                                                else "train"))
        if paper:
            found = {**result["metrics"], **_own_mmd(
                mmd_protocol, data.skeleton, sets["generated"], sets["train"], sets["test"], paper,
                repeats, seed, bandwidths)}
            result["metrics"] = {name: found[name] for name in metrics if name in found}
    except MetricError as exc:
        raise EvaluationError(str(exc)) from None
    result["protocol"] = {"name": protocol_name, "description": PROTOCOLS.get(protocol_name),
                          **result["protocol"]}
    result["mmd_protocol"] = {"name": mmd_protocol, "description": protocol.MMD_PROTOCOLS.get(mmd_protocol)}
    return {
        "dataset": data.name,
        "skeleton": data.skeleton,
        "source": motions[0].source,
        "n_motions": len(motions),
        "frames": frames,
        "fps": fps,
        "actions": {a: sum(m.action == a for m in motions) for a in actions},
        "repeats": int(repeats),
        "seed": int(seed),
        "real": {"split": split.describe(), "n_test": len(test), "n_train": len(train)},
        "classifier": None if classifier is None else {
            "dataset": classifier.dataset, "iterations": classifier.iteration,
            "test_accuracy": classifier.test_accuracy,
        },
        **result,
    }


def _own_mmd(name, skeleton, generated, train, test, metrics, repeats, seed, bandwidths) -> dict:
    """Return MMD_avg / MMD_seq by the ``paper`` or ``authors`` protocol (skeleton: its name)."""
    if name == "paper":
        return protocol.paper_mmd(generated, train, test, metrics, repeats, seed, bandwidths)
    from motion_metrics.authors_mmd import authors_mmd

    return authors_mmd(generated, train, test, metrics, repeats, seed,
                       skeleton=get_skeleton(skeleton), bandwidths=bandwidths)


def _check_motions(data: Dataset, motions: list[Motion]) -> tuple[int, float]:
    """Return the motions' shared length and frame rate, or raise saying what does not fit."""
    if not motions:
        raise EvaluationError("no motions to evaluate")
    for i, motion in enumerate(motions):
        if motion.skeleton != data.skeleton:
            raise EvaluationError(
                f"motion {i} ({motion.action!r}, source {motion.source!r}) has skeleton "
                f"{motion.skeleton!r}, but dataset {data.name!r} is {data.skeleton!r}; evaluate "
                f"against a dataset of skeleton {motion.skeleton!r}"
            )
        motion.check_finite()
    lengths = sorted({m.frames for m in motions})
    if len(lengths) > 1:
        raise EvaluationError(
            f"motions have different lengths ({', '.join(map(str, lengths))} frames); the "
            f"metrics compare clips of one length: sample them all with the same --frames"
        )
    rates = sorted({m.fps for m in motions})
    if len(rates) > 1:
        raise EvaluationError(f"motions have different frame rates ({rates}); resample them to one")
    known = set(data.actions())
    unknown = sorted({m.action for m in motions} - known)
    if unknown:
        raise EvaluationError(
            f"dataset {data.name!r} has no action {', '.join(map(repr, unknown))}; its actions "
            f"are {', '.join(data.actions())}: evaluate against the dataset the motions imitate"
        )
    return lengths[0], float(rates[0])


def _check_classifier(data: Dataset, classifier: ActionClassifier, frames: int, fps: float,
                      actions: list[str]) -> None:
    if classifier.skeleton != data.skeleton:
        raise EvaluationError(
            f"the classifier reads skeleton {classifier.skeleton!r}, but dataset {data.name!r} is "
            f"{data.skeleton!r}; pass a classifier trained on {data.name!r}"
        )
    if classifier.dataset and classifier.dataset != data.name:
        raise EvaluationError(
            f"the classifier was trained on dataset {classifier.dataset!r}, not {data.name!r}; "
            f"train one on {data.name!r} (manage.py train_classifier --dataset {data.name})"
        )
    if classifier.frames != frames:
        raise EvaluationError(
            f"the motions have {frames} frames, the classifier reads {classifier.frames}; "
            f"sample {classifier.frames}-frame motions or train a classifier with --frames {frames}"
        )
    if abs(classifier.fps - fps) > 1e-3 * fps:
        raise EvaluationError(
            f"the motions are at {fps:g} fps, the classifier at {classifier.fps:g} fps; resample "
            f"the motions or train a classifier with --fps {fps:g}"
        )
    unknown = [a for a in actions if a not in classifier.actions]
    if unknown:
        raise EvaluationError(
            f"the classifier knows no action {', '.join(map(repr, unknown))}; its actions are "
            f"{', '.join(classifier.actions)}: pass a classifier trained on these actions"
        )


def _motion_set(motions: list[Motion], index: dict, classifier, key: str) -> protocol.MotionSet:
    """Return motions as arrays: joints from their start above the origin, labels, classifier outputs."""
    joints = np.stack([m.joints for m in motions]).astype(np.float64)
    skeleton = get_skeleton(motions[0].skeleton)
    root = joints[:, :, skeleton.root]
    start = root[:, 0].copy()
    start[:, skeleton.up_index] = 0.0
    features = predictions = None
    if classifier is not None:
        try:
            features, predictions = classifier.features_and_predictions(joints, f"{key} motions")
        except ClassifierError as exc:
            raise EvaluationError(str(exc)) from None
    return protocol.MotionSet(
        joints=joints - start[:, None, None, :],
        labels=np.array([index[m.action] for m in motions]),
        features=features,
        predictions=predictions,
        end_points=root[:, -1] - root[:, 0],
    )


def _optional(values, count: int, name: str) -> np.ndarray | None:
    if values is None:
        return None
    values = np.asarray(values)
    if len(values) != count:
        raise EvaluationError(f"{name} has {len(values)} entries for {count} motions; give one per motion")
    return values
