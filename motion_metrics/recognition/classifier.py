"""The action classifier behind the feature metrics (seed 000, Sec. 4.2.1).

Action2Motion "train[s] a standard RNN action recognition classifier for each dataset,
and use[s] its final layer as the motion feature extractor"; its released classifier is
a 2-layer GRU of 128 units whose last output goes through a 30-unit tanh layer (the
features) and a linear layer to the classes. The paper gives no training settings; we
take Adam at 1e-3 with batches of 128. Options beyond it (the ``augmented`` preset of
:class:`~motion_metrics.recognition.networks.ClassifierConfig`): a temporal convolution
beside the GRU, and training on mirrored and slightly rotated clips.

Poses enter as joint positions relative to the root in each frame, plus the root's path
from its first position on the floor (height kept), each value standardised by the
training clips' mean and standard deviation, which travel with the checkpoint together
with the config, actions, skeleton, clip length and frame rate, and the held-out split
with the accuracy and confusion matrix measured on it.

Training runs up to a number of iterations with early stopping: a seeded share of the
training takes is set aside for validation, the network is measured on it every few
iterations, training stops once it has not improved for ``patience`` measurements, and
the best measured state is kept (never the held-out clips: they only report).
"""

from __future__ import annotations

import copy
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from motion.datasets import DatasetError, get_dataset
from motion.motion import Motion
from motion_metrics.recognition.augment import Augmenter
from motion_metrics.recognition.errors import ClassifierError
from motion_metrics.recognition.networks import FEATURES, ClassifierConfig, GRURecogniser
from motion_metrics.recognition.split import VALIDATION_FRACTION, Split, make_split, validation_split
from generation.sampling import choose
from motion.skeletons import get_skeleton

CHECKPOINT_FORMAT = 1
KIND = "action_classifier"
INFERENCE_BATCH = 512
EVAL_EVERY = 50  # iterations between validation measurements
PATIENCE = 10  # measurements without improvement before training stops


@contextmanager
def one_thread():
    """Run torch on one thread, then restore the setting.

    A GRU step is a small matrix product: a second thread gains little, and when other
    processes share the cores, torch's waiting threads make it several times slower.
    """
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)



class ActionClassifier:
    """A GRU action recogniser whose 30-d tanh layer gives the motion features."""

    def __init__(self, config: ClassifierConfig | None, skeleton: str, actions: Sequence[str],
                 fps: float, frames: int):
        self.config = config or ClassifierConfig()
        self.skeleton = get_skeleton(skeleton).name
        if isinstance(actions, str) or len(actions) < 2 or len(set(actions)) != len(actions):
            raise ClassifierError(f"a classifier needs at least two distinct actions; got {actions!r}")
        self.actions = list(actions)
        self.fps = float(fps)
        self.frames = int(frames)
        skel = get_skeleton(skeleton)
        self.pose_size = (skel.n_joints + 1) * skel.dims
        self.mean: np.ndarray | None = None
        self.std: np.ndarray | None = None
        self.iteration = 0
        self.seed: int | None = None
        self.loss: float | None = None
        # Set when trained on a dataset (train_classifier) and kept in the checkpoint.
        self.dataset: str | None = None
        self.split: Split | None = None
        self.test_accuracy: float | None = None
        self.train_accuracy: float | None = None
        self.n_train = self.n_test = 0
        self.test_confusion: list[list[int]] | None = None
        # Early stopping (fit with validation clips): the kept iteration and its measurement.
        self.best_iteration: int | None = None
        self.validation_accuracy: float | None = None
        self.validation_loss: float | None = None
        self.stopped_early = False
        self.history: list[dict] = []
        self.n_validation = 0
        self._build(0)

    def __repr__(self):
        return (f"<ActionClassifier on {self.skeleton}: {len(self.actions)} actions, "
                f"{self.frames} frames at {self.fps:g} fps, {self.iteration} iterations>")

    def _build(self, seed: int) -> None:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.network = GRURecogniser(self.pose_size, self.config.hidden, self.config.layers,
                                         len(self.actions), self.config.temporal)
        self.optimizer = torch.optim.Adam(self.network.parameters(), lr=self.config.lr)

    # Inputs.

    def joints_of(self, motions, what: str = "motions") -> np.ndarray:
        """Return checked joints ``(N, frames, J, D)`` of a list of :class:`Motion` or an array."""
        skeleton = get_skeleton(self.skeleton)
        if isinstance(motions, np.ndarray):
            joints = motions
        else:
            motions = list(motions)
            for i, motion in enumerate(motions):
                where = f"{what}[{i}] ({motion.action!r}, source {motion.source!r})"
                if motion.skeleton != self.skeleton:
                    raise ClassifierError(
                        f"{where} has skeleton {motion.skeleton!r}; this classifier reads "
                        f"{self.skeleton!r}: use a classifier trained on that skeleton's dataset"
                    )
                if abs(motion.fps - self.fps) > 1e-3 * self.fps:
                    raise ClassifierError(
                        f"{where} is at {motion.fps:g} fps; this classifier reads {self.fps:g} fps: "
                        f"resample the motions (motion.ops.resample) or train a classifier "
                        f"at their rate"
                    )
                if motion.frames != self.frames:
                    raise ClassifierError(
                        f"{where} has {motion.frames} frames; this classifier reads clips of "
                        f"{self.frames} frames: sample motions of {self.frames} frames or train a "
                        f"classifier with --frames {motion.frames}"
                    )
            if not motions:
                raise ClassifierError(f"no {what} given")
            joints = np.stack([m.joints for m in motions])
        if joints.ndim != 4 or joints.shape[2:] != (skeleton.n_joints, skeleton.dims):
            raise ClassifierError(
                f"{what} must be (N, T, {skeleton.n_joints}, {skeleton.dims}) joints of "
                f"{self.skeleton!r}; got {joints.shape}"
            )
        if joints.shape[1] != self.frames:
            raise ClassifierError(
                f"{what} have {joints.shape[1]} frames; this classifier reads clips of "
                f"{self.frames} frames: sample motions of {self.frames} frames or train a "
                f"classifier with --frames {joints.shape[1]}"
            )
        if not np.isfinite(joints).all():
            raise ClassifierError(f"{what} have non-finite joint coordinates; drop or repair them")
        return np.asarray(joints, dtype=np.float64)

    def pose_features(self, joints: np.ndarray) -> np.ndarray:
        """Return unnormalised inputs ``(N, T, pose_size)``: root-relative joints and the root's path."""
        skeleton = get_skeleton(self.skeleton)
        root = joints[:, :, skeleton.root]
        start = root[:, :1].copy()
        start[..., skeleton.up_index] = 0.0  # keep the height above the floor
        local = joints - root[:, :, None]
        count, frames = joints.shape[:2]
        return np.concatenate([local.reshape(count, frames, -1), root - start], axis=-1)

    def encode(self, motions, what: str = "motions") -> torch.Tensor:
        """Return standardised network inputs ``(N, T, pose_size)`` float32."""
        if self.mean is None:
            raise ClassifierError("this classifier has not been trained; call fit or load a checkpoint")
        poses = (self.pose_features(self.joints_of(motions, what)) - self.mean) / self.std
        return torch.from_numpy(poses.astype(np.float32))

    def labels_of(self, motions: Sequence[Motion]) -> np.ndarray:
        """Return the action indices ``(N,)`` of motions; actions the classifier lacks are an error."""
        index = {action: i for i, action in enumerate(self.actions)}
        unknown = sorted({m.action for m in motions if m.action not in index})
        if unknown:
            raise ClassifierError(
                f"this classifier knows no action {', '.join(map(repr, unknown))}; its actions "
                f"are {', '.join(self.actions)}: use a classifier trained on the motions' dataset"
            )
        return np.array([index[m.action] for m in motions], dtype=np.int64)

    # Training.

    def fit(self, clips: Sequence[Motion], iters: int, seed: int = 0, progress: bool = True,
            validation: Sequence[Motion] | None = None, patience: int | None = None,
            eval_every: int = EVAL_EVERY) -> float:
        """Train for up to ``iters`` iterations on ``clips`` with cross-entropy; return the last loss.

        A fresh classifier takes its input statistics from ``clips`` and is initialised from
        ``seed``; iteration ``i`` draws its batch from a generator seeded by ``(seed, i)``.

        With ``validation`` clips, the network is measured on them every ``eval_every``
        iterations and after the last; the best measurement (higher accuracy, then lower
        loss) is kept and its state restored at the end. With ``patience``, training stops
        after that many measurements in a row without improvement.
        """
        if int(iters) != iters or iters < 0:
            raise ClassifierError(f"iters must be a non-negative integer; got {iters!r}")
        if int(eval_every) != eval_every or eval_every < 1:
            raise ClassifierError(f"eval_every must be a positive integer; got {eval_every!r}")
        if patience is not None and (int(patience) != patience or patience < 1):
            raise ClassifierError(f"patience must be a positive integer or None; got {patience!r}")
        if patience is not None and not validation:
            raise ClassifierError("early stopping (patience) needs validation clips; none given")
        clips = list(clips)
        if not clips:
            raise ClassifierError("no training clips; check the dataset, subjects and actions")
        labels = torch.from_numpy(self.labels_of(clips))
        if self.mean is None:
            self._build(int(seed))
            poses = self.pose_features(self.joints_of(clips, "training clips"))
            flat = poses.reshape(-1, poses.shape[-1])
            self.mean = flat.mean(0)
            std = flat.std(0)
            # Root-relative root coordinates are always 0: give them a floor, not a 1/0.
            self.std = np.maximum(std, 1e-3 * max(float(std.max()), 1e-12))
        self.seed = int(seed)
        augment = Augmenter(get_skeleton(self.skeleton), self.config.mirror, self.config.rotate)
        if augment.active:  # batches are augmented before they are standardised
            inputs = torch.from_numpy(self.pose_features(
                self.joints_of(clips, "training clips")).astype(np.float32))
        else:
            inputs, augment = self.encode(clips, "training clips"), None
        loss_fn = nn.CrossEntropyLoss()
        if validation:
            validation = list(validation)
            check = (self.encode(validation, "validation clips"),
                     torch.from_numpy(self.labels_of(validation)))
            self.n_validation = len(validation)
            self.history, self.stopped_early = [], False
        best, best_state, waited = None, None, 0
        bar = tqdm(total=int(iters), desc=f"classifier {self.skeleton}", unit="it",
                   disable=not progress, dynamic_ncols=True)
        self.network.train()
        try:
            with one_thread():
                for step in range(1, int(iters) + 1):
                    hits = self._step(inputs, labels, loss_fn, augment)
                    bar.set_postfix({"loss": f"{self.loss:.4g}", "acc": f"{hits:.2f}"}, refresh=False)
                    bar.update(1)
                    if not validation or (step % int(eval_every) and step != int(iters)):
                        continue
                    accuracy, loss = self._measure(*check, loss_fn)
                    self.history.append({"iteration": self.iteration, "accuracy": accuracy, "loss": loss})
                    if best is None or (accuracy, -loss) > best:
                        best, waited = (accuracy, -loss), 0
                        best_state = copy.deepcopy(self.network.state_dict())
                        self.best_iteration = self.iteration
                        self.validation_accuracy, self.validation_loss = accuracy, loss
                    else:
                        waited += 1
                        if patience is not None and waited >= patience:
                            self.stopped_early = step < int(iters)
                            break
        finally:
            bar.close()
            if best_state is not None:
                self.network.load_state_dict(best_state)
            self.network.eval()
        return self.loss if self.loss is not None else float("nan")

    def _measure(self, inputs: torch.Tensor, labels: torch.Tensor, loss_fn) -> tuple[float, float]:
        """Return the accuracy and mean loss on ``inputs``, then go back to training mode."""
        self.network.eval()
        with torch.no_grad():
            logits = torch.cat([self.network(inputs[start:start + INFERENCE_BATCH])
                                for start in range(0, len(inputs), INFERENCE_BATCH)])
        self.network.train()
        return float((logits.argmax(1) == labels).float().mean()), float(loss_fn(logits, labels))

    def _step(self, inputs: torch.Tensor, labels: torch.Tensor, loss_fn,
              augment: Augmenter | None = None) -> float:
        """Run one optimisation step on a seeded batch; return the batch accuracy.

        With ``augment``, ``inputs`` are the unstandardised pose features and each batch is
        augmented, then standardised.
        """
        generator = torch.Generator().manual_seed((self.seed * 1_000_003 + self.iteration) % 2**63)
        size = self.config.batch_size
        if len(inputs) >= size:
            batch = torch.randperm(len(inputs), generator=generator)[:size]
        else:
            batch = torch.randint(len(inputs), (size,), generator=generator)
        poses = inputs[batch]
        if augment is not None:
            skeleton = get_skeleton(self.skeleton)
            shape = poses.shape
            rows = augment(poses.view(*shape[:2], skeleton.n_joints + 1, skeleton.dims), generator)
            mean = torch.from_numpy(np.asarray(self.mean, dtype=np.float32))
            std = torch.from_numpy(np.asarray(self.std, dtype=np.float32))
            poses = (rows.reshape(shape) - mean) / std
        logits = self.network(poses)
        loss = loss_fn(logits, labels[batch])
        self.optimizer.zero_grad()
        loss.backward()
        self.optimizer.step()
        self.iteration += 1
        self.loss = loss.item()
        return float((logits.argmax(1) == labels[batch]).float().mean())

    # Inference.

    def _outputs(self, motions, what: str) -> tuple[np.ndarray, np.ndarray]:
        inputs = self.encode(motions, what)
        features, logits = [], []
        self.network.eval()
        with torch.no_grad(), one_thread():
            for start in range(0, len(inputs), INFERENCE_BATCH):
                feats = self.network.features(inputs[start:start + INFERENCE_BATCH])
                features.append(feats.numpy())
                logits.append(self.network.output(feats).numpy())
        if not features:
            return np.zeros((0, FEATURES)), np.zeros((0, len(self.actions)))
        return np.concatenate(features).astype(np.float64), np.concatenate(logits)

    def features(self, motions, what: str = "motions") -> np.ndarray:
        """Return the 30-d tanh features ``(N, 30)`` of motions (list of Motion or joints array)."""
        return self._outputs(motions, what)[0]

    def predict(self, motions, what: str = "motions") -> np.ndarray:
        """Return the predicted action indices ``(N,)`` (into :attr:`actions`)."""
        return self._outputs(motions, what)[1].argmax(1)

    def features_and_predictions(self, motions, what: str = "motions") -> tuple[np.ndarray, np.ndarray]:
        """Return :meth:`features` and :meth:`predict` from one pass."""
        features, logits = self._outputs(motions, what)
        return features, logits.argmax(1)

    def accuracy(self, motions: Sequence[Motion], what: str = "motions") -> float:
        """Return the share of motions whose action is predicted."""
        motions = list(motions)
        if not motions:
            raise ClassifierError(f"no {what} to measure accuracy on")
        return float(np.mean(self.predict(motions, what) == self.labels_of(motions)))

    def confusion(self, motions: Sequence[Motion], what: str = "motions") -> np.ndarray:
        """Return counts ``(A, A)``: row = true action, column = predicted (order of :attr:`actions`)."""
        motions = list(motions)
        if not motions:
            raise ClassifierError(f"no {what} to measure a confusion matrix on")
        counts = np.zeros((len(self.actions), len(self.actions)), dtype=np.int64)
        np.add.at(counts, (self.labels_of(motions), self.predict(motions, what)), 1)
        return counts

    def confusion_text(self) -> str:
        """Return the held-out confusion matrix as aligned text (rows true, columns predicted)."""
        if self.test_confusion is None:
            return "(no held-out confusion matrix)"
        width = max(max(len(a) for a in self.actions), 6)
        lines = [" " * width + "  " + " ".join(f"{a[:width]:>{width}}" for a in self.actions)]
        for action, row in zip(self.actions, self.test_confusion):
            lines.append(f"{action:>{width}}  " + " ".join(f"{n:>{width}d}" for n in row))
        return "\n".join(lines)

    # Checkpoints.

    def to_checkpoint(self) -> dict:
        return {
            "format": CHECKPOINT_FORMAT,
            "kind": KIND,
            "config": self.config.to_dict(),
            "skeleton": self.skeleton,
            "actions": list(self.actions),
            "fps": self.fps,
            "frames": self.frames,
            "mean": torch.from_numpy(np.asarray(self.mean)),
            "std": torch.from_numpy(np.asarray(self.std)),
            "network": self.network.state_dict(),
            "iteration": self.iteration,
            "seed": self.seed,
            "loss": self.loss,
            "dataset": self.dataset,
            "split": self.split.to_dict() if self.split else None,
            "test_accuracy": self.test_accuracy,
            "train_accuracy": self.train_accuracy,
            "n_train": self.n_train,
            "n_test": self.n_test,
            "test_confusion": self.test_confusion,
            "best_iteration": self.best_iteration,
            "validation_accuracy": self.validation_accuracy,
            "validation_loss": self.validation_loss,
            "stopped_early": self.stopped_early,
            "history": self.history,
            "n_validation": self.n_validation,
        }

    def save(self, path: str | Path) -> Path:
        """Write the checkpoint (weights, config, input statistics, split, accuracy) to ``path``."""
        if self.mean is None:
            raise ClassifierError("this classifier has not been trained; there is nothing to save")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(path.name + ".partial")  # never leave a truncated file
        torch.save(self.to_checkpoint(), partial)
        os.replace(partial, path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "ActionClassifier":
        """Return the classifier saved at ``path``."""
        path = Path(path)
        if not path.is_file():
            raise ClassifierError(
                f"classifier checkpoint {path} does not exist; train one with manage.py train_classifier"
            )
        try:
            checkpoint = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:  # torch raises many types for truncated or foreign files
            raise ClassifierError(
                f"{path} is not a readable checkpoint ({type(exc).__name__}); train the classifier again"
            ) from None
        if not isinstance(checkpoint, dict) or checkpoint.get("kind") != KIND:
            raise ClassifierError(
                f"{path} is not an action classifier checkpoint (a method checkpoint?); pass the "
                f"file written by manage.py train_classifier"
            )
        if checkpoint.get("format") != CHECKPOINT_FORMAT:
            raise ClassifierError(
                f"{path} is in format {checkpoint.get('format')!r}; this version reads {CHECKPOINT_FORMAT}"
            )
        try:
            model = cls(ClassifierConfig(**checkpoint["config"]), checkpoint["skeleton"],
                        checkpoint["actions"], checkpoint["fps"], checkpoint["frames"])
            model.network.load_state_dict(checkpoint["network"])
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            raise ClassifierError(
                f"{path} holds an unusable classifier ({str(exc).splitlines()[0]}); train it again"
            ) from None
        model.mean = checkpoint["mean"].numpy()
        model.std = checkpoint["std"].numpy()
        model.iteration = int(checkpoint["iteration"])
        model.seed, model.loss = checkpoint.get("seed"), checkpoint.get("loss")
        model.dataset = checkpoint.get("dataset")
        model.split = Split.from_dict(checkpoint["split"]) if checkpoint.get("split") else None
        model.test_accuracy = checkpoint.get("test_accuracy")
        model.train_accuracy = checkpoint.get("train_accuracy")
        model.n_train, model.n_test = checkpoint.get("n_train", 0), checkpoint.get("n_test", 0)
        model.test_confusion = checkpoint.get("test_confusion")
        model.best_iteration = checkpoint.get("best_iteration")
        model.validation_accuracy = checkpoint.get("validation_accuracy")
        model.validation_loss = checkpoint.get("validation_loss")
        model.stopped_early = bool(checkpoint.get("stopped_early", False))
        model.history = list(checkpoint.get("history") or [])
        model.n_validation = checkpoint.get("n_validation", 0)
        model.network.eval()
        return model


def train_classifier(dataset: str, out: str | Path, *, data_root=None, subjects=None,
                     test_subjects=None, actions=None, frames: int | None = None,
                     fps: float | None = None, iters: int = 2000, preset: str = "paper",
                     seed: int = 0, progress: bool = True, patience: int | None = PATIENCE,
                     eval_every: int = EVAL_EVERY, validation: float = VALIDATION_FRACTION,
                     config: ClassifierConfig | None = None) -> ActionClassifier:
    """Train a classifier on ``dataset``'s training clips, measure it on held-out clips, save to ``out``.

    See :func:`make_split` for what is held out. A seeded ``validation`` share of the
    training takes (:func:`validation_split`) drives early stopping: up to ``iters``
    iterations, measured every ``eval_every``, stopping after ``patience`` measurements
    without improvement (``None``: run all ``iters``), keeping the best state. ``config``
    (default: the ``preset``'s) sets the network and augmentation. The held-out accuracy and confusion matrix are stored in the checkpoint. What
    ``manage.py train_classifier`` runs.
    """
    data = get_dataset(dataset, data_root)
    actions = choose(actions, data.actions(), "action", f"dataset {dataset!r}")
    frames = frames or data.clip_frames
    clips = data.clips(frames=frames, fps=fps, actions=actions)
    split = make_split(data, clips, test_subjects=test_subjects, subjects=subjects, seed=seed)
    train, test = split.divide(clips)
    if not train or not test:
        raise DatasetError(
            f"dataset {dataset!r} gave {len(train)} training and {len(test)} held-out clips of "
            f"{frames} frames ({split.describe()}); both sides need clips: check --data-root, "
            f"--subjects, --test-subjects and --frames"
        )
    missing = sorted(set(actions) - {clip.action for clip in train})
    if missing:
        raise DatasetError(f"no training clips of {', '.join(missing)}; pick other --subjects or actions")
    fitting, checking = validation_split(train, validation, seed)
    if not checking:
        raise DatasetError(
            f"dataset {dataset!r} has no action with two training takes to validate on; "
            f"add training --subjects or --actions"
        )
    missing = sorted(set(actions) - {clip.action for clip in fitting})
    if missing:
        raise DatasetError(f"no clips of {', '.join(missing)} left to fit after the validation share")
    config = ClassifierConfig.preset(preset) if config is None else config
    model = ActionClassifier(config, data.skeleton, actions, clips[0].fps, frames)
    model.fit(fitting, iters, seed=seed, progress=progress, validation=checking, patience=patience,
              eval_every=eval_every)
    model.dataset, model.split = data.name, split
    model.n_train, model.n_test = len(fitting), len(test)
    model.train_accuracy = model.accuracy(fitting, "training clips")
    model.test_accuracy = model.accuracy(test, "held-out clips")
    model.test_confusion = model.confusion(test, "held-out clips").tolist()
    model.save(out)
    return model
