"""The method sources of a build: their checkpoints (one per training seed), samples and metrics.

A method source without ``checkpoint`` trains one checkpoint per training seed
(``seeds``, else ``seed``) through the project's one training loop
(:func:`generation.methods.budget.train_within_budget`, as ``compare_methods``), with
the recipe of its preset, schedule and budget (:func:`generation.methods.schedule.recipe_for`),
on the build's clips of its training subjects, into
``<cache>/checkpoints/<source>-<key>/<method>-seed<k>.pt`` beside a record of its
iterations. With the benchmark schedule, the benchmark's training subjects, preset,
budget and seed this is the checkpoint ``compare_methods`` trains, weight for weight.

The source's clips come from its checkpoints in turn: clip ``i`` of an action from the
``(i mod S)``-th training seed, each carrying its training seed and checkpoint sha256
(the stimulus' ``training_seed`` and ``checkpoint``, columns of the export). Every
checkpoint is measured on the build's dataset (:func:`motion_metrics.checkpoint_metrics.measure`:
MMD, APD and n-APD always, FID, accuracy, diversity and multimodality with a classifier)
against clips of subjects the build does not train on; the manifest's ``sources`` and
``metrics`` hold per source and seed the checkpoint, its budget and its numbers, so the
analysis report can set human scores beside what each checkpoint is. A measurement that
fails is a note in the manifest; the build goes on.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from studyapp.stimuli.source_config import ConfigError
from studyapp.stimuli.clips import file_hash

# Metrics of the report's table, in order, with their headers.
TABLE_METRICS = {"fid": "FID", "accuracy": "accuracy", "diversity": "diversity",
                 "multimodality": "multimodality", "mmd_avg": "MMD_avg", "mmd_seq": "MMD_seq",
                 "n_apd": "n-APD"}


def digest(value) -> str:
    return hashlib.sha256(json.dumps(value, sort_keys=True, default=str).encode()).hexdigest()


@dataclass
class Trained:
    """One checkpoint of a method source: its training seed, file, hash and budget."""

    seed: int | None
    path: Path
    sha256: str
    iterations: int
    recipe: str | None  # preset and changes (None for a given checkpoint)
    given: bool
    phases: list | None = None  # iterations per training phase (:func:`training_phases`)

    def manifest(self) -> dict:
        return {"training_seed": self.seed, "checkpoint": self.sha256, "iterations": self.iterations,
                "recipe": self.recipe, "given": self.given, "phases": self.phases}


def training_phases(method: str, config, iterations: int) -> list[dict] | None:
    """Return the iterations of each training phase of ``iterations`` in all, or None.

    A method trained in phases (:data:`generation.methods.schedule.PHASES`) gives its
    first phase (its config field, what it does, its iterations) and the rest, e.g.
    ``[{"phase": "pretrain_iters", "what": "pretrains its frame decoder", "iterations": 500},
    {"phase": "rest", "what": "the rest of the training", "iterations": 500}]``.
    """
    from generation.methods.schedule import first_phase

    found = first_phase(method, config)
    if found is None:
        return None
    phase, length = found
    first = min(length, iterations)
    return [{"phase": phase.field, "what": phase.what, "iterations": first},
            {"phase": "rest", "what": "the rest of the training", "iterations": iterations - first}]


class MethodSources:
    """Checkpoints, samples and metrics of a build's method sources (see the module)."""

    def __init__(self, build):
        self.build = build
        self._trained: dict[str, list[Trained]] = {}
        self._classifier = None
        self._classifier_ready = False
        self._default_split = None
        self.notes: list[str] = []

    @property
    def config(self):
        return self.build.config

    # --- checkpoints -------------------------------------------------------------------

    def folder(self, source) -> Path:
        """Return the cache folder of a source's trained checkpoints (one file per seed)."""
        c = self.config
        section = {k: v for k, v in source.section().items() if k not in ("seed", "seeds")}
        data = {"dataset": c.dataset, "subjects": c.subjects, "actions": c.actions,
                "frames": c.frames, "fps": c.fps}
        return self.build.cache / "checkpoints" / f"{source.name}-{digest([section, data])[:16]}"

    def planned(self, source) -> list[tuple[int, bool]]:
        """Return ``(training seed, trained already?)`` of a source's automatic checkpoints."""
        return [(seed, self._finished(source, seed) is not None) for seed in source.training_seeds()]

    def recipe(self, source):
        from generation.methods.schedule import recipe_for

        return recipe_for(source.method, source.preset, source.iters, source.schedule,
                          source.changes)

    def departures(self, source) -> dict:
        """Return the switches of a trained source's config that differ from the paper's
        (:func:`generation.methods.schedule.departures`: e.g. sa_gcn's ``init: he``)."""
        from generation.methods import get_method
        from generation.methods.schedule import departures

        return departures(self.recipe(source).config(get_method(source.method)))

    def _finished(self, source, seed) -> dict | None:
        """Return the record of a finished checkpoint of ``seed`` for this budget, or None."""
        from generation.methods import get_method

        folder = self.folder(source)
        path, record_path = folder / f"{source.method}-seed{seed}.pt", folder / f"{source.method}-seed{seed}.json"
        if not (path.is_file() and record_path.is_file()):
            return None
        record = json.loads(record_path.read_text())
        cls = get_method(source.method)
        signature = record.get("signature", {})
        if (record.get("finished") and record.get("iterations") == source.iters
                and signature.get("version") == cls.version and signature.get("seed") == seed
                and signature.get("config") == json.loads(json.dumps(
                    self.recipe(source).config(cls).to_dict()))):
            return record
        return None

    def trained(self, source) -> list[Trained]:
        """Return a method source's checkpoints, training those that are missing."""
        if source.name not in self._trained:
            self._trained[source.name] = (self._given(source) if source.checkpoint
                                          else [self._train(source, seed)
                                                for seed in source.training_seeds()])
        return self._trained[source.name]

    def _given(self, source) -> list[Trained]:
        from generation.methods.base import read_checkpoint

        path = self.config.path(source.checkpoint)
        if not path.is_file():
            raise ConfigError(f"sources: checkpoint {source.checkpoint!r} of {source.name!r} "
                              f"is not there (looked in {path}); fix the path, or drop "
                              f"'checkpoint' to train one with train.iters")
        raw = read_checkpoint(path)
        phases = None
        try:
            from generation.methods import get_method

            config = get_method(source.method).Config.from_dict(dict(raw["config"]))
            phases = training_phases(source.method, config, int(raw["iteration"]))
        except Exception:  # noqa: BLE001 - an older config: its phases are not known, the rest is
            phases = None
        return [Trained(raw.get("seed"), path, file_hash(path), int(raw["iteration"]), None, True,
                        phases)]

    def _train(self, source, seed) -> Trained:
        from generation.methods.budget import train_within_budget
        from motion_metrics.recognition import one_thread

        folder = self.folder(source)
        recipe = self.recipe(source)
        record = self._finished(source, seed)
        if record is None:
            c = self.config
            self.build.log(f"training {source.method} (seed {seed}) for {source.iters} iterations "
                           f"({recipe.describe()}, {source.schedule} schedule)")
            clips = self.build.dataset.clips(frames=c.frames or self.build.dataset.clip_frames,
                                             fps=c.fps, subjects=c.subjects,
                                             actions=self.build.actions())
            with one_thread():
                _, record = train_within_budget(source.method, clips, self.build.actions(), None,
                                                folder, recipe, seed, iters=source.iters)
        from generation.methods import get_method

        path = folder / f"{source.method}-seed{seed}.pt"
        iterations = int(record["iterations"])
        return Trained(seed, path, file_hash(path), iterations, recipe.describe(), False,
                       training_phases(source.method, recipe.config(get_method(source.method)),
                                       iterations))

    # --- samples -----------------------------------------------------------------------

    def sample(self, source, actions, n: int, frames: int) -> list:
        """Return ``n`` motions per action, action by action, from the checkpoints in turn."""
        from generation.sampling import sample_method
        from motion_metrics.recognition import one_thread

        trained = self.trained(source)
        count = len(trained)
        drawn = []
        with one_thread():
            for k, checkpoint in enumerate(trained):
                share = len(range(k, n, count))  # clips k, k + S, ... of each action
                motions = (sample_method(checkpoint.path, actions, share, frames, source.seed,
                                         source.method) if share else [])
                drawn.append([m.with_joints(m.joints, meta={
                    **m.meta, "training_seed": checkpoint.seed, "checkpoint": checkpoint.sha256})
                    for m in motions])
        out = []
        for a, _ in enumerate(actions):
            for i in range(n):
                k = i % count
                share = len(range(k, n, count))
                out.append(drawn[k][a * share + i // count])
        return out

    # --- metrics -----------------------------------------------------------------------

    def held_out(self):
        """Return the split the metrics hold out and whether the methods trained on it too.

        A classifier's own split wins (the metrics measure against its held-out clips).
        """
        from motion_metrics.recognition import Split, make_split

        c, data = self.config, self.build.dataset
        classifier = self._classifier if self._classifier_ready else None
        if classifier is not None and classifier.split is not None:
            held = classifier.split.test_subjects
            trained_on = held is None or c.subjects is None or bool(set(held) & set(c.subjects))
            return classifier.split, trained_on
        if data.subjects is not None and c.subjects:
            rest = tuple(s for s in data.subjects if s not in c.subjects)
            if not rest:
                return None, False
            return Split(test_subjects=rest, train_subjects=tuple(c.subjects)), False
        if self._default_split is None:
            clips = data.clips(frames=c.frames or data.clip_frames, fps=c.fps,
                               actions=self.build.actions())
            self._default_split = make_split(data, clips)
        return self._default_split, True

    def classifier(self):
        """Return the classifier of the feature metrics (given, trained into the cache, or None)."""
        if self._classifier_ready:
            return self._classifier
        self._classifier_ready = True
        m, c = self.config.metrics, self.config
        from motion_metrics.recognition import ActionClassifier, train_classifier

        if m.classifier:
            self._classifier = ActionClassifier.load(c.path(m.classifier))
        elif m.train_classifier:
            split, _ = self.held_out()
            key = digest({"data": self.build.data_fields(), "iters": m.classifier_iters,
                          "preset": m.classifier_preset, "seed": c.seed,
                          "split": None if split is None else split.to_dict()})[:16]
            path = self.build.cache / "classifiers" / f"{c.dataset}-{key}.pt"
            if path.is_file():
                self._classifier = ActionClassifier.load(path)
            else:
                self.build.log(f"training the metrics' classifier on {c.dataset} "
                               f"({m.classifier_preset}, up to {m.classifier_iters} iterations)")
                test = None if split is None else split.test_subjects
                self._classifier = train_classifier(
                    c.dataset, path, data_root=c.data_root, subjects=c.subjects,
                    test_subjects=test, actions=self.build.actions(),
                    frames=c.frames or self.build.dataset.clip_frames, fps=c.fps,
                    iters=m.classifier_iters, preset=m.classifier_preset, seed=c.seed,
                    progress=False)
        return self._classifier

    def measure(self, source) -> list[dict]:
        """Return the metrics of each of a method source's checkpoints (cached by inputs)."""
        from generation.methods import load_checkpoint
        from motion_metrics.checkpoint_metrics import measure
        from motion_metrics.recognition import one_thread

        m = self.config.metrics
        out = []
        for checkpoint in self.trained(source):
            try:
                classifier = self.classifier()
                split, trained_on = self.held_out()
                if split is None:
                    raise ValueError("every subject of the dataset trains the methods, so none is "
                                     "held out to measure against; leave some out of subjects")
                # Sampled and resampled with the training seed, as compare_methods measures.
                seed = self.config.seed if checkpoint.seed is None else checkpoint.seed
                key = digest({"checkpoint": checkpoint.sha256, "n": m.n, "repeats": m.repeats,
                              "mmd_protocol": m.mmd_protocol, "seed": seed,
                              "split": split.to_dict(), "data": self.build.data_fields(),
                              "classifier": None if classifier is None else
                              [classifier.iteration, classifier.test_accuracy, classifier.seed,
                               classifier.config.to_dict()]})[:16]
                cached = self.build.cache / "metrics" / f"{source.name}-{key}.json"
                if cached.is_file():
                    found = json.loads(cached.read_text())
                else:
                    self.build.log(f"measuring {source.name} (training seed {checkpoint.seed})")
                    with one_thread():
                        found = measure(load_checkpoint(checkpoint.path), self.build.dataset,
                                        classifier, n=m.n, repeats=m.repeats, seed=seed,
                                        mmd_protocol=m.mmd_protocol, split=split)
                    found["held_out_trained_on"] = trained_on
                    cached.parent.mkdir(parents=True, exist_ok=True)
                    cached.write_text(json.dumps(found, sort_keys=True, allow_nan=False))
                    found = json.loads(cached.read_text())  # as a rebuild reads it: one key order
            except (ValueError, RuntimeError, OSError) as exc:  # Evaluation/Classifier/DatasetError
                self.notes.append(f"{source.name} (training seed {checkpoint.seed}): metrics not "
                                  f"measured: {exc}")
                found = None
            out.append(found)
        return out

    def manifest(self, sources) -> tuple[list[dict], dict]:
        """Return the manifest's ``sources`` (method sources, their checkpoints and metrics) and
        ``metrics`` (how they were measured)."""
        m = self.config.metrics
        entries = []
        for source in sources:
            if source.kind != "method":
                continue
            measured = self.measure(source) if m.enabled else [None] * len(self.trained(source))
            entries.append({
                "source": source.name, "method": source.method,
                "preset": None if source.checkpoint else source.preset,
                "schedule": None if source.checkpoint else source.schedule,
                "iters": None if source.checkpoint else source.iters,
                "config": source.changes or None,
                "departures": None if source.checkpoint else self.departures(source),
                "checkpoints": [{**t.manifest(), "metrics": found}
                                for t, found in zip(self.trained(source), measured)],
            })
        about = {"enabled": m.enabled, "n": m.n, "repeats": m.repeats, "mmd_protocol": m.mmd_protocol,
                 "notes": list(self.notes)}
        classifier = self._classifier if m.enabled and entries else None
        if classifier is not None:
            about["classifier"] = {"iterations": classifier.iteration, "preset": m.classifier_preset
                                   if not m.classifier else None,
                                   "test_accuracy": classifier.test_accuracy,
                                   "held_out": classifier.split.describe() if classifier.split else None}
        elif m.enabled and entries:
            about["classifier"] = None
            about["notes"].append("FID, accuracy, diversity and multimodality not measured: no "
                                  "classifier (set metrics.classifier, or metrics.train_classifier: true)")
        return entries, about


def sources_table(manifest: dict) -> pd.DataFrame | None:
    """Return one row per method source and training seed of a build manifest, or None.

    Columns: source, training seed, checkpoint (its sha256's first 12 digits), preset,
    schedule, iterations, phases (of a method trained in phases), then each metric of :data:`TABLE_METRICS` measured (the mean
    over the measurement's repeats), with a first row of the Real values.
    """
    rows, real = [], {}
    for entry in manifest.get("sources") or []:
        for checkpoint in entry["checkpoints"]:
            row = {"source": entry["source"], "training seed": checkpoint.get("training_seed"),
                   "checkpoint": (checkpoint.get("checkpoint") or "")[:12],
                   "preset": checkpoint.get("recipe") or entry.get("preset") or "given",
                   "schedule": entry.get("schedule") or "", "iterations": checkpoint.get("iterations"),
                   "phases": phases_text(checkpoint.get("phases"))}
            for name, header in TABLE_METRICS.items():
                value = ((checkpoint.get("metrics") or {}).get("metrics") or {}).get(name)
                row[header] = None if not value else value["mean"]
                if value and value.get("real") and header not in real:
                    real[header] = value["real"]["mean"]
            rows.append(row)
    if not rows:
        return None
    columns = list(rows[0])
    real_row = {"source": "Real (held-out vs training clips)", **{k: real.get(k) for k in columns
                                                                   if k in TABLE_METRICS.values()}}
    table = pd.DataFrame([real_row, *rows], columns=columns)
    return table.dropna(axis=1, how="all")


def phases_text(phases) -> str | None:
    """Return ``"pretrain_iters 500 + rest 500"`` for a checkpoint's phases, or None."""
    if not phases:
        return None
    return " + ".join(f"{p['phase']} {p['iterations']:,}" for p in phases)


# Metrics the report's sentences name, in order, with their names and digits.
SENTENCE_METRICS = {"fid": ("FID", 3), "accuracy": ("accuracy", 3), "diversity": ("diversity", 3),
                    "mmd_avg": ("MMD_avg", 3), "n_apd": ("n-APD", 3)}


def sources_sentences(manifest: dict) -> list[str]:
    """Return one sentence per method source of a build manifest: which checkpoints its
    clips come from (training budget, phases, seed, sha256 prefix) and their objective
    metrics at build time (the mean over the measurement's repeats, per checkpoint), so the
    report reads every human score beside what the checkpoint is, e.g. "Clips of a2m come
    from a checkpoint trained 1,000 iterations with training seed 0 (sha256 0123456789ab;
    demo preset, benchmark schedule): FID 12.1, accuracy 0.205, MMD_avg 0.57"."""
    out = []
    for entry in manifest.get("sources") or []:
        checkpoints = entry.get("checkpoints") or []
        if not checkpoints:
            continue
        given = all(c.get("given") for c in checkpoints)
        recipe = ("a given checkpoint" if given else
                  f"{entry.get('preset')} preset, {entry.get('schedule')} schedule")
        changed = entry.get("config") or {}
        if changed:
            recipe += ", with " + ", ".join(f"{k}={v}" for k, v in changed.items())
        if entry.get("departures"):
            recipe += ("; departures from the paper: "
                       + ", ".join(f"{k}={v}" for k, v in entry["departures"].items()))
        parts = [_checkpoint_text(c) for c in checkpoints]
        if len(parts) == 1:
            text, numbers = parts[0]
            out.append(f"Clips of {entry['source']} come from a checkpoint {text}; {recipe})"
                       + (f": {numbers}" if numbers else ""))
        else:
            each = "; ".join(f"one {text})" + (f": {numbers}" if numbers else "")
                             for text, numbers in parts)
            out.append(f"Clips of {entry['source']} come from {len(parts)} checkpoints in turn "
                       f"({recipe}): {each}")
    return out


def _checkpoint_text(checkpoint: dict) -> tuple[str, str]:
    """Return what a manifest checkpoint is (budget, seed, hash and phases; the caller
    closes its parenthesis) and its metrics' text."""
    iterations = checkpoint.get("iterations")
    text = f"trained {iterations:,} iterations" if iterations is not None else "of an unknown budget"
    seed = checkpoint.get("training_seed")
    text += (f" with training seed {seed}" if seed is not None else " with no recorded training seed")
    text += f" (sha256 {(checkpoint.get('checkpoint') or '')[:12]}"
    phases = checkpoint.get("phases")
    if phases:
        text += f"; it {phases[0]['what']} for the first {phases[0]['iterations']:,}"
    measured = (checkpoint.get("metrics") or {}).get("metrics") or {}
    numbers = ", ".join(f"{label} {value['mean']:.{digits}g}"
                        for name, (label, digits) in SENTENCE_METRICS.items()
                        if (value := measured.get(name)) and value.get("mean") is not None)
    if not numbers and checkpoint.get("metrics") is None:
        numbers = "no metrics measured at build time"
    return text, numbers
