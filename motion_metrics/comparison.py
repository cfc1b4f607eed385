"""Train every method under an equal budget, with several seeds, and measure it as the seed papers did.

What ``manage.py compare_methods`` runs. For each data setting (:data:`SETTINGS`) the
action classifier is trained on the training subjects and measured on the held-out
ones; then each method trains once per training seed, for ``iters`` iterations (the same
for every method) or ``budget`` seconds of wall time, and each seed's model draws ``n``
motions per action and is evaluated (:func:`motion_metrics.evaluate.evaluate`, the
``bootstrap`` protocol) with the metrics of the papers whose tables the setting compares
with (:mod:`motion_metrics.paper_numbers`). Per metric the results hold each seed's value
with its interval over samples, and the mean over seeds with a t interval over seeds.

The checkpoint evaluated is the last of each training or, with ``selection``
best-mmd-seq (:class:`Selection`), the one with the lowest MMD_seq against the training
clips among candidates kept every ``every`` iterations of the same budget, as seeds
003/004 chose theirs. MMD_avg and MMD_seq are measured by ``mmd_protocol``
(:data:`motion_metrics.protocol.MMD_PROTOCOLS`), which the results name.

Everything lands in ``work``: per setting the classifier, and per method and seed its
checkpoint, its samples (``.npz``) and a record (``.json``) of the seconds spent,
iterations, selection and evaluation (``<method>-seed<k>.*``; under best-mmd-seq
``<method>-seed<k>-best-mmd-seq-every<N>-n<M>.*``, with the candidates in a folder of
that name, so the two selections never share a cache). Checkpoints are written every
``checkpoint_every`` seconds, so an interrupted run resumes where it stopped, and a rerun
with the same budget and selection reuses all of it.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import time
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
from tqdm import tqdm

from motion.datasets import get_dataset
from motion.datasets.base import DATASETS
from motion.formats import npz
from generation.methods import Method, MethodError, get_method, list_methods
from generation.methods.budget import (
    candidate_path,
    read_json,
    train_within_budget,
    write_json,
)
from generation.methods.schedule import Recipe, departures
from generation.methods.schedule import recipe_for as schedule_recipe
from motion_metrics import recognition
from motion.motion import MotionError
from motion_metrics.recognition import ActionClassifier, ClassifierError, one_thread, train_classifier
from motion.skeletons import get_skeleton
from motion_metrics.checkpoint_metrics import sample_for_metrics
from motion_metrics.evaluate import EvaluationError, evaluate, training_mmd
from motion_metrics.protocol import MMD_PROTOCOLS
from scipy import stats

H36M_TRAIN = ("S1", "S5", "S6", "S7", "S8")
H36M_TEST = ("S9",)  # the papers test on S11, which our copy of Human3.6M lacks
METRICS_2D = ("mmd_avg", "mmd_seq", "accuracy", "fid", "diversity", "multimodality")
METRICS_3D = ("fid", "accuracy", "diversity", "multimodality")
DEFAULT_SEEDS = (0, 1, 2)
# How MMD_avg / MMD_seq are measured by default (motion_metrics.protocol.MMD_PROTOCOLS); tables name it.
MMD_PROTOCOL = "heldout"
# Which checkpoint of a training is evaluated (compare_methods --select).
SELECTIONS = {
    "last": "the last checkpoint of each training",
    "best-mmd-seq": "of candidate checkpoints kept every N iterations of the same budget (and the "
                    "last), the one with the lowest MMD_seq against the training clips by the paper "
                    "MMD protocol, as seeds 003/004 select theirs",
}
# Scoring a candidate: motions per action (default), repeats of the paper protocol, and the
# offset of the sampling seed from the training seed, so that a candidate is chosen on
# other motions than the ones its evaluation then draws (with the training seed).
SELECT_N = 50
SELECT_REPEATS = 3
SELECT_SEED_OFFSET = 1_000_000


class ComparisonError(ValueError):
    """A comparison cannot run as asked (unknown dataset or method, no clips, bad budget)."""


@dataclass(frozen=True)
class Selection:
    """Which checkpoint of each training is evaluated: the last, or the best by MMD_seq.

    ``best-mmd-seq`` keeps a candidate every ``every`` iterations (and the last) and
    scores each by MMD_seq of ``n`` motions per action against the training clips
    (:func:`candidate_score`).
    """

    rule: str = "last"
    every: int | None = None
    n: int = SELECT_N

    def __post_init__(self):
        if self.rule not in SELECTIONS:
            raise ComparisonError(f"unknown checkpoint selection {self.rule!r}; choose from "
                                 f"{', '.join(SELECTIONS)}")
        if not self.best:
            if self.every is not None:
                raise ComparisonError("candidates every N iterations go with the best-mmd-seq "
                                     "selection, not with last")
            return
        if self.every is None or int(self.every) != self.every or self.every < 1:
            raise ComparisonError(f"best-mmd-seq needs candidates every N >= 1 iterations; "
                                 f"got {self.every!r}")
        if int(self.n) != self.n or self.n < 2:
            raise ComparisonError(f"best-mmd-seq scores at least 2 motions per action; got {self.n!r}")

    @property
    def best(self) -> bool:
        return self.rule == "best-mmd-seq"

    def key(self) -> str:
        """Return what the file names of this selection's runs add (nothing for the last)."""
        return f"-best-mmd-seq-every{self.every}-n{self.n}" if self.best else ""

    def to_dict(self) -> dict:
        if not self.best:
            return {"rule": self.rule}
        return {"rule": self.rule, "every": self.every, "n": self.n, "repeats": SELECT_REPEATS,
                "seed_offset": SELECT_SEED_OFFSET}

    def candidates(self, final: int) -> list[int]:
        """Return the iterations scored for a training that ended at ``final``."""
        return sorted({*range(self.every, final, self.every), final}) if self.best else [final]


LAST = Selection()


@dataclass(frozen=True)
class Setting:
    """A dataset with its split, the metrics to measure and the paper tables to compare with."""

    dataset: str
    train_subjects: tuple[str, ...] | None
    test_subjects: tuple[str, ...] | None
    metrics: tuple[str, ...]
    tables: tuple[str, ...]  # keys of motion_metrics.paper_numbers.TABLES


SETTINGS = {
    "h36m2d": Setting("h36m2d", H36M_TRAIN, H36M_TEST, METRICS_2D,
                      ("004_table_1", "003_table_1", "004_table_2")),
    "h36m": Setting("h36m", H36M_TRAIN, H36M_TEST, METRICS_3D, ("000_table_1",)),
    "demo": Setting("demo", None, None, METRICS_3D, ("000_table_1",)),
}


def setting_for(dataset: str, subjects=None, test_subjects=None) -> Setting:
    """Return the setting of ``dataset``, with other training or held-out subjects if given.

    Datasets without an entry in :data:`SETTINGS` get the 2D papers' metrics and tables
    for 2D skeletons, A2M's for 3D, and the dataset's default split. Subjects are
    ignored for datasets without subjects (their held-out clips are whole takes).
    """
    try:
        cls = DATASETS.get(dataset)
    except KeyError as exc:
        raise ComparisonError(exc.args[0]) from None
    setting = SETTINGS.get(dataset)
    if setting is None:
        flat = get_skeleton(cls.skeleton).dims == 2
        setting = Setting(dataset, None, None, METRICS_2D if flat else METRICS_3D,
                          SETTINGS["h36m2d" if flat else "h36m"].tables)
    changes = {}
    if cls.subjects is None:
        return setting
    if subjects:
        changes["train_subjects"] = tuple(subjects)
    if test_subjects:
        changes["test_subjects"] = tuple(test_subjects)
    return replace(setting, **changes)


def recipe_for(method: str, presets: dict[str, str] | None = None,
               iters: int | None = None) -> Recipe:
    """Return the recipe ``compare_methods`` trains ``method`` with for ``iters`` iterations.

    The ``demo`` preset (or the one ``presets`` names for the method) under the
    ``benchmark`` schedule (:mod:`generation.methods.schedule`): a first phase longer than
    its share of the budget is shortened to that share. The paper presets need hours
    (A2M: 40,000 iterations; the GAN baselines pretrain for 10,000); the demo presets
    (smaller networks, batches of 32) learn something in a minute of one core.
    """
    return schedule_recipe(method, (presets or {}).get(method, "demo"), iters, "benchmark")


def run_stem(method: str, seed: int, selection: Selection = LAST, iters: int | None = None) -> str:
    """Return the file name (without suffix) of ``method``'s run with training ``seed``, budget
    ``iters`` (none for a time budget) and ``selection``."""
    budget = "" if iters is None else f"-it{iters}"
    return f"{method}-seed{seed}{budget}{selection.key()}"


def start_from_shorter(folder: Path, method: str, seed: int, selection: Selection, iters: int) -> None:
    """Copy the longest finished shorter run of the same method and seed to this budget's files.

    :func:`generation.methods.budget.train_within_budget` then resumes it to ``iters`` if
    its recipe and config are this budget's too (a method whose first phase takes a share of
    the budget has another config at another budget, and trains afresh): a budget sweep
    trains a method without phases once, to its largest budget, keeping every budget's
    checkpoint.
    """
    target = folder / f"{run_stem(method, seed, selection, iters)}.pt"
    if target.is_file():
        return
    shorter = []
    for record_path in folder.glob(f"{method}-seed{seed}-it*{selection.key()}.json"):
        budget = record_path.stem[len(f"{method}-seed{seed}-it"):].removesuffix(selection.key())
        record = read_json(record_path)
        if budget.isdigit() and int(budget) < iters and record.get("finished"):
            shorter.append((int(budget), record_path))
    if shorter:
        _, record_path = max(shorter)
        shutil.copyfile(record_path.with_suffix(".pt"), target)
        shutil.copyfile(record_path, target.with_suffix(".json"))
        candidates = record_path.with_suffix(".candidates")  # best-mmd-seq: its scored candidates
        if candidates.is_dir():
            shutil.copytree(candidates, target.with_suffix(".candidates"), dirs_exist_ok=True)


def candidate_score(model: Method, train: Sequence, n: int, seed: int) -> float:
    """Return MMD_seq of ``n`` motions per action of ``model`` against the training clips ``train``.

    The paper MMD protocol (:func:`motion_metrics.evaluate.training_mmd`, coordinates
    standardised by the training clips, equal paired counts), over :data:`SELECT_REPEATS`
    repeats; the motions are sampled with ``seed`` + :data:`SELECT_SEED_OFFSET`.
    """
    motions = model.sample([action for action in model.actions for _ in range(n)],
                           seed=seed + SELECT_SEED_OFFSET)
    return training_mmd(motions, train, "mmd_seq", SELECT_REPEATS, seed)


def select_checkpoint(model: Method, record: dict, folder: Path, clips, selection: Selection,
                      on_tick: Callable[[str], None] | None = None) -> tuple[Method, dict]:
    """Return the candidate of ``model``'s training with the lowest MMD_seq, and the selection's record.

    ``model`` is the finished last checkpoint of a run of :func:`train_within_budget`
    under ``selection`` (its ``record``, which keeps the scores, so a rerun scores only
    new candidates). Each other candidate is loaded, finished as the last was (ODMO fits
    its modes) and scored by :func:`candidate_score`; a candidate that cannot sample
    (diverged) is not chosen. Once all are scored, only the best of the candidates kept
    every ``selection.every`` iterations stays on disk, for a later, longer run.
    """
    seed = record["signature"]["seed"]
    stem = run_stem(record["signature"]["method"], seed, selection, record.get("iters"))
    finish = type(model).fit is not Method.fit
    final = model.iteration
    state = record.setdefault("selection", {"scores": {}, "seconds": 0.0})
    scores = state["scores"]  # iteration (as text: JSON keys) -> MMD_seq, or None
    start = time.perf_counter()
    for iteration in selection.candidates(final):
        if str(iteration) in scores:
            continue
        if on_tick:
            on_tick(f"seed {seed}: scoring the checkpoint of iteration {iteration}")
        path = candidate_path(folder, stem, iteration)
        candidate = model if iteration == final else type(model).load(path)
        if candidate is not model and finish:
            candidate.fit(clips, 0, seed=seed, progress=False)  # finished as the last one was
        try:
            scores[str(iteration)] = candidate_score(candidate, clips, selection.n, seed)
        except (MethodError, EvaluationError, MotionError):
            scores[str(iteration)] = None
        if iteration % selection.every == 0 and (finish or not path.is_file()):
            candidate.save(path)  # finished, should a longer run choose it
        state["seconds"] += time.perf_counter() - start
        start = time.perf_counter()
        write_json(folder / f"{stem}.json", record)
    scored = {it: scores[str(it)] for it in selection.candidates(final) if scores[str(it)] is not None}
    chosen = state["chosen"] = min(scored, key=scored.get) if scored else final
    kept = min((it for it in scored if it % selection.every == 0), key=scored.get, default=None)
    for iteration in selection.candidates(final):
        if iteration % selection.every == 0 and iteration != kept:
            candidate_path(folder, stem, iteration).unlink(missing_ok=True)
    write_json(folder / f"{stem}.json", record)
    return (model if chosen == final else type(model).load(candidate_path(folder, stem, chosen))), state


def t_interval(values: Sequence[float], level: float = 0.95) -> float | None:
    """Return the half-width of the ``level`` t interval of the mean of ``values`` (None for fewer than 2)."""
    values = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    if len(values) < 2:
        return None
    quantile = stats.t.ppf(0.5 + level / 2, len(values) - 1)
    return float(quantile * values.std(ddof=1) / np.sqrt(len(values)))


def combine_seeds(runs: Sequence[dict]) -> dict:
    """Return per metric the mean over ``runs`` (one evaluation per seed) and both intervals.

    ``ci_seeds`` is the half-width of the 95 % t interval over the seeds' means (``len -
    1`` degrees of freedom); ``ci_samples`` is the mean of the seeds' own 95 % intervals
    over samples (the evaluation protocol's), also kept per seed under ``seeds``.
    """
    names = [name for name in runs[0]["metrics"]] if runs else []
    out = {}
    for name in names:
        rows = [run["metrics"].get(name) or {} for run in runs]
        means = [row.get("mean") for row in rows]
        finite = [m for m in means if m is not None and np.isfinite(m)]
        cis = [row.get("ci") for row in rows if row.get("ci") is not None and np.isfinite(row["ci"])]
        out[name] = {
            "mean": float(np.mean(finite)) if finite else None,
            "ci_seeds": t_interval(finite),
            "ci_samples": float(np.mean(cis)) if cis else None,
            "seeds": [{"seed": run["seed"], "mean": row.get("mean"), "ci": row.get("ci")}
                      for run, row in zip(runs, rows)],
        }
        held = [(row.get("heldout") or {}).get("mean") for row in rows]
        held = [m for m in held if m is not None and np.isfinite(m)]
        if held:  # the authors' MMD protocol: the same motions against the held-out clips
            out[name]["heldout"] = {"mean": float(np.mean(held)), "ci_seeds": t_interval(held)}
    return out


def per_class_accuracy(classifier: ActionClassifier, motions) -> dict[str, float]:
    """Return the classifier's accuracy on ``motions`` per action, and over all as ``accuracy``."""
    motions = list(motions)
    hits = classifier.predict(motions) == classifier.labels_of(motions)
    actions = np.array([m.action for m in motions])
    out = {action: float(hits[actions == action].mean()) for action in classifier.actions
           if (actions == action).any()}
    out["accuracy"] = float(hits.mean())
    return out


def prepare_classifier(setting: Setting, folder: Path, iters: int, preset: str, seed: int,
                       data_root=None, actions=None) -> tuple[ActionClassifier, dict]:
    """Return the setting's classifier (trained on its training subjects, or loaded) and its record."""
    path, record_path = folder / "classifier.pt", folder / "classifier.json"
    signature = {"dataset": setting.dataset, "train": setting.train_subjects,
                 "test": setting.test_subjects, "iters": iters, "preset": preset, "seed": seed,
                 "actions": actions,
                 "early_stopping": {"patience": recognition.PATIENCE, "every": recognition.EVAL_EVERY,
                                    "validation": recognition.VALIDATION_FRACTION}}
    record = read_json(record_path)
    if record.get("signature") == json.loads(json.dumps(signature)) and path.is_file():
        return ActionClassifier.load(path), record
    start = time.perf_counter()
    model = train_classifier(setting.dataset, path, data_root=data_root,
                             subjects=setting.train_subjects, test_subjects=setting.test_subjects,
                             actions=actions, iters=iters, preset=preset, seed=seed, progress=False)
    record = {"signature": signature, "seconds": time.perf_counter() - start}
    write_json(record_path, record)
    return model, record


def machine() -> dict:
    """Return what the numbers were measured on: CPU, cores, GPU, versions, load."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": model, "cores": cores,
        "gpu": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        "python": platform.python_version(), "torch": torch.__version__, "numpy": np.__version__,
        "load": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
    }


def run_comparison(datasets: Sequence[str], budget: float | None, work: str | Path, *,
                  iters: int | None = None, seeds: Sequence[int] = DEFAULT_SEEDS,
                  methods: Sequence[str] | None = None, presets: dict[str, str] | None = None,
                  repeats: int = 20, n: int = 100, subjects=None,
                  test_subjects=None, actions=None, classifier_iters: int = 500,
                  classifier_preset: str = "augmented", data_root=None, checkpoint_every: float = 15.0,
                  mmd_protocol: str = MMD_PROTOCOL, selection: Selection = LAST,
                  progress: bool = True, log: Callable[[str], None] | None = None) -> dict:
    """Compare ``methods`` (default: all) on each dataset; return the results (JSON-ready).

    Each method trains once per seed of ``seeds``, for ``iters`` iterations or ``budget``
    seconds (give one); the classifier trains with the first seed. ``selection`` says
    which checkpoint of each training is evaluated, ``mmd_protocol`` how MMD_avg and
    MMD_seq are measured. Also written to ``work/results.json``;
    :func:`motion_metrics.comparison_report.render` turns them into Markdown.
    """
    methods = list(methods or list_methods())
    unknown = [name for name in methods if name not in list_methods()]
    if unknown:
        raise ComparisonError(f"unknown method {', '.join(map(repr, unknown))}; choose from "
                             f"{', '.join(list_methods())}")
    if (budget is None) == (iters is None):
        raise ComparisonError("give either a time budget (seconds) or iterations per method, not both")
    if (budget is not None and not budget > 0) or (iters is not None and iters < 1):
        raise ComparisonError(f"the budget must be positive; got {budget if iters is None else iters}")
    if repeats < 1 or n < 2:
        raise ComparisonError(f"repeats must be at least 1 and n at least 2; got {repeats}, {n}")
    seeds = [int(seed) for seed in seeds]
    if not seeds or len(set(seeds)) != len(seeds) or min(seeds) < 0:
        raise ComparisonError(f"seeds must be distinct non-negative integers; got {seeds}")
    if mmd_protocol not in MMD_PROTOCOLS:
        raise ComparisonError(f"unknown MMD protocol {mmd_protocol!r}; choose from "
                             f"{', '.join(sorted(MMD_PROTOCOLS))}")
    if selection.best and iters is not None and selection.every > iters:
        raise ComparisonError(f"candidates every {selection.every} iterations leave none but the "
                             f"last within {iters} iterations; take at most {iters}")
    work = Path(work)
    settings = [setting_for(name, subjects, test_subjects) for name in datasets]
    started = datetime.now(timezone.utc)
    clock = time.perf_counter()
    result = {"started": started.isoformat(timespec="seconds"), "machine": machine(),
              "budget": budget, "iters": iters, "seeds": seeds, "repeats": repeats, "n": n,
              "classifier_iters": classifier_iters, "classifier_preset": classifier_preset,
              "mmd_protocol": mmd_protocol, "selection": selection.to_dict(),
              "methods": methods, "settings": []}
    bar = tqdm(total=len(settings) * (1 + len(methods) * len(seeds)), desc="compare_methods", unit="step",
               disable=not progress, dynamic_ncols=True)

    def say(message: str) -> None:
        if log:
            with tqdm.external_write_mode():
                log(message)

    try:
        with one_thread():
            for setting in settings:
                result["settings"].append(_run_setting(
                    setting, methods, presets, budget, iters, work / setting.dataset, repeats, seeds, n,
                    actions, classifier_iters, classifier_preset, data_root, checkpoint_every,
                    bar, say, mmd_protocol=mmd_protocol, selection=selection))
    finally:
        bar.close()
    result["wall_seconds"] = time.perf_counter() - clock
    result["load_at_end"] = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    write_json(work / "results.json", result)
    return result


def _run_setting(setting, methods, presets, budget, iters, folder, repeats, seeds, n, actions,
                 classifier_iters, classifier_preset, data_root, checkpoint_every, bar, say, *,
                 mmd_protocol, selection) -> dict:
    """Return one setting's results: data, classifier, Real column and every method."""
    name = setting.dataset
    bar.set_description(f"{name}: classifier")
    data = get_dataset(name, data_root)
    classifier, clf_record = prepare_classifier(setting, folder, classifier_iters, classifier_preset,
                                                seeds[0], data_root, actions)
    clips = data.clips(actions=classifier.actions)
    train, test = classifier.split.divide(clips)
    if not train or not test:
        raise ComparisonError(f"dataset {name!r} gave {len(train)} training and {len(test)} "
                             f"held-out clips ({classifier.split.describe()})")
    out = {
        "dataset": name, "skeleton": data.skeleton, "frames": classifier.frames,
        "fps": classifier.fps, "actions": list(classifier.actions), "metrics": list(setting.metrics),
        "tables": list(setting.tables), "split": classifier.split.to_dict(),
        "split_text": classifier.split.describe(), "n_train": len(train), "n_test": len(test),
        "classifier": {
            "preset": classifier_preset, "hidden": classifier.config.hidden,
            "layers": classifier.config.layers, "iterations": classifier.iteration,
            "mirror": classifier.config.mirror, "rotate": classifier.config.rotate,
            "temporal": classifier.config.temporal,
            "seconds": clf_record.get("seconds"), "test_accuracy": classifier.test_accuracy,
            "train_accuracy": classifier.train_accuracy,
            "per_class": per_class_accuracy(classifier, test),
            "best_iteration": classifier.best_iteration,
            "validation_accuracy": classifier.validation_accuracy,
            "n_validation": classifier.n_validation, "n_fit": classifier.n_train,
            "stopped_early": classifier.stopped_early,
            "confusion": classifier.confusion(test, "held-out clips").tolist(),
        },
        "real": None, "protocol": None, "mmd_protocol": mmd_protocol,
        "selection": selection.to_dict(), "methods": {},
    }
    bar.update(1)
    say(f"{name}: classifier ({classifier.iteration} iterations): accuracy "
        f"{classifier.test_accuracy:.3f} on {len(test)} held-out clips ({classifier.split.describe()})")
    for method in methods:
        bar.set_description(f"{name}: {method}")
        entry = _run_method(method, setting, data, classifier, train, presets, budget, iters,
                            folder, repeats, seeds, n, checkpoint_every, bar,
                            mmd_protocol=mmd_protocol, selection=selection)
        out["methods"][method] = entry
        if out["real"] is None and entry.get("real"):
            out["real"] = entry["real"]
        done = [run for run in entry.get("runs") or [] if run.get("metrics")]
        if "000_table_1" in setting.tables and out.get("real_a2m") is None and done:
            # Action2Motion's own Real row: two draws of the held-out clips.
            out["real_a2m"] = _real_of_two_draws(data, folder, method, done[0], classifier,
                                                 setting, repeats, selection, iters)
        if out["protocol"] is None and entry.get("protocol"):
            out["protocol"] = entry["protocol"]
        say(_summary_line(name, method, entry))
    return out


def _run_method(method, setting, data, classifier, train, presets, budget, iters, folder,
                repeats, seeds, n, checkpoint_every, bar, *, mmd_protocol, selection) -> dict:
    """Train, sample and evaluate one method once per seed; errors are recorded, not raised."""
    recipe = recipe_for(method, presets, iters)
    entry = {"recipe": recipe.describe(), "runs": [],
             "departures": departures(recipe.config(get_method(method)))}
    for seed in seeds:
        bar.set_description(f"{setting.dataset}: {method} (seed {seed})")
        entry["runs"].append(_run_seed(method, setting, data, classifier, train, recipe, budget,
                                       iters, folder, repeats, seed, n, checkpoint_every, bar,
                                       mmd_protocol=mmd_protocol, selection=selection))
        bar.update(1)
    done = [run for run in entry["runs"] if run.get("metrics")]
    errors = [f"seed {run['seed']}: {run['error']}" for run in entry["runs"] if run.get("error")]
    if errors:
        entry["errors"] = errors
        if not done:
            entry["error"] = errors[0].split(": ", 1)[1]
    trained = [run for run in entry["runs"] if run.get("seconds") is not None]
    for key in ("seconds", "cpu_seconds", "finish_seconds", "select_seconds", "evaluate_seconds"):
        values = [run.get(key) for run in entry["runs"] if run.get(key) is not None]
        entry[key] = sum(values) if values else None
    entry["iterations"] = [run["iterations"] for run in trained]
    if selection.best:
        entry["chosen"] = [run.get("chosen") for run in trained]
    entry["parameters"] = trained[0]["parameters"] if trained else None
    entry["reused"] = sum(bool(run.get("reused")) for run in trained)
    if done:
        entry["metrics"] = combine_seeds(done)
        entry["real"] = done[0]["real"]
        entry["protocol"] = done[0].get("protocol")
        actions = done[0]["per_class"].keys()
        entry["per_class"] = {action: float(np.mean([run["per_class"][action] for run in done]))
                              for action in actions}
    return entry


def _run_seed(method, setting, data, classifier, train, recipe, budget, iters, folder, repeats,
              seed, n, checkpoint_every, bar, *, mmd_protocol, selection) -> dict:
    """Train, select a checkpoint of, sample and evaluate one method with one training seed."""
    entry = {"seed": seed}
    stem = run_stem(method, seed, selection, iters)
    if iters is not None:
        start_from_shorter(folder, method, seed, selection, iters)

    def tick(text):
        bar.set_postfix_str(text, refresh=True)

    try:
        model, record = train_within_budget(
            method, train, classifier.actions, budget, folder, recipe, seed, checkpoint_every,
            on_tick=tick, iters=iters, stem=stem,
            keep_every=selection.every if selection.best else None,
            extra_signature={"selection": selection.to_dict()} if selection.best else None)
    except (MethodError, ValueError, RuntimeError) as exc:
        entry["error"] = f"training failed: {exc}"
        return entry
    entry.update({key: record.get(key) for key in
                  ("seconds", "cpu_seconds", "iterations", "finish_seconds", "parameters",
                   "reused")})
    if selection.best:
        try:
            model, chosen = select_checkpoint(model, record, folder, train, selection, tick)
        except (MethodError, ValueError, RuntimeError) as exc:
            entry["error"] = f"checkpoint selection failed: {exc}"
            return entry
        entry.update({"chosen": chosen["chosen"], "select_seconds": chosen["seconds"],
                      "scores": chosen["scores"]})
    tick(f"seed {seed}: sampling and evaluating")
    signature = {"iteration": model.iteration, "n": n, "repeats": repeats, "seed": seed,
                 "metrics": list(setting.metrics), "classifier": classifier.iteration,
                 "classifier_config": classifier.config.to_dict(),
                 "classifier_accuracy": classifier.test_accuracy,
                 "split": classifier.split.to_dict(), "mmd_protocol": mmd_protocol}
    cached = record.get("evaluation")
    if cached and cached.get("signature") == json.loads(json.dumps(signature)):
        entry.update(cached["values"])
        return entry
    try:
        start = time.perf_counter()
        motions = sample_for_metrics(model, classifier.actions, n, seed)  # as a build measures
        npz.save(folder / f"{stem}.npz", motions)
        values = evaluate(data, motions, classifier, setting.metrics, repeats, seed,
                          mmd_protocol=mmd_protocol)
        found = {
            "metrics": {key: {"mean": row["mean"], "ci": row["ci"],
                              **({"heldout": {"mean": row["heldout"]["mean"],
                                              "ci": row["heldout"]["ci"]}}
                                 if row.get("heldout") else {})}
                        for key, row in values["metrics"].items()},
            "real": {key: {"mean": row["real"]["mean"], "ci": row["real"]["ci"]}
                     for key, row in values["metrics"].items() if row["real"]},
            "protocol": values.get("protocol", {}).get("name"),
            "per_class": per_class_accuracy(classifier, motions),
            "evaluate_seconds": time.perf_counter() - start,
        }
    except (MethodError, EvaluationError, ClassifierError, MotionError) as exc:
        entry["error"] = f"sampling or evaluation failed: {exc}"
        return entry
    record["evaluation"] = {"signature": signature, "values": found}
    write_json(folder / f"{stem}.json", record)
    entry.update(found)
    return entry


def _real_of_two_draws(data, folder, method, run, classifier, setting, repeats, selection,
                       iters) -> dict | None:
    """Return the Real values of Action2Motion's definition (held-out against held-out clips)."""
    path = folder / f"{run_stem(method, run['seed'], selection, iters)}.npz"
    if not path.is_file():
        return None
    metrics = [m for m in setting.metrics if not m.startswith("mmd_")]
    values = evaluate(data, npz.load(path), classifier, metrics, repeats, run["seed"],
                      real_reference="test")
    return {key: {"mean": row["real"]["mean"], "ci": row["real"]["ci"]}
            for key, row in values["metrics"].items() if row["real"]}


def _summary_line(dataset: str, method: str, entry: dict) -> str:
    if entry.get("error"):
        return f"{dataset} {method}: {entry['error']}"
    values = ", ".join(
        f"{key} {row['mean']:.4g}" + (f" ± {row['ci_seeds']:.2g}" if row["ci_seeds"] is not None else "")
        for key, row in entry["metrics"].items() if row["mean"] is not None)
    seeds = len(entry["runs"])
    chosen = (f" (evaluated: {'/'.join(map(str, entry['chosen']))}, by MMD_seq)"
              if entry.get("chosen") else "")
    return (f"{dataset} {method} [{entry['recipe']}]: {seeds} seeds, iterations "
            f"{'/'.join(map(str, entry['iterations']))}{chosen} in {entry['seconds']:.0f} s; "
            f"mean over seeds {values}")
