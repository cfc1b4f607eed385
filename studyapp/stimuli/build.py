"""Build a study's stimuli from a config: sample, render, register, write a manifest.

This is the one way stimuli are made: ``build_stimuli CONFIG``, the admin's build jobs
and the demo (``studies/demo/*.yaml``) all run it. The study's type says which extra
clips it needs (:meth:`StudyType.stimulus_roles`: catch, practice, reference, examples,
anchors); the build makes them with :mod:`motion.perturb` (catch clips from a spare
clip of every source, :mod:`studyapp.stimuli.catch_clips`; the others from real clips),
renders everything with one framing, registers the clips and lets the type finish the
study (:meth:`StudyType.after_register`, e.g. scoring standards).

A cache folder (shared between studies by default: ``<var>/stimuli/cache``) holds what is
keyed on its inputs, so a rebuild only redoes what a changed field touches, and studies
built from the same sources share their motions and clips:

- ``motions/<source>-<key>.npz``: a source's motions; the key hashes the source's config
  section, the dataset fields, the checkpoint's (or file's) sha256 and the seed;
- ``motions/<source>-catch-<key>.npz``: the spare clip per action of each source that
  its catch clips are made from (keyed as the source's motions, one more per action).
- ``checkpoints/<source>-<key>/<method>-seed<k>.pt``: methods without a ``checkpoint``
  are trained here, one checkpoint per training seed, with the stated budget
  (``iters``, ``preset``, ``schedule``), as ``compare_methods`` trains
  (:mod:`studyapp.stimuli.sources`), and measured (``metrics/``, ``classifiers/``);
- ``renders/<video_hash>.mp4|png`` and ``renders/index.json``: each clip's render,
  keyed by its motion hash, the style, the size and the framing.
  They are drawn by processes of this machine (:func:`render_workers`), or with
  ``workers="celery"`` by Celery render workers on machines that mount the cache folder
  (:mod:`studyapp.stimuli.render_fanout`); registration stays here either way.

The framing is fitted to real clips only (``clips_per_source + 3`` per action, drawn
with the config's seed), never to generated ones: changing a method then re-renders only
that method's clips, and catch, reference and example clips are framed exactly like the
judged ones.

``manifest.json`` (in the study's own folder) lists per clip its source, checkpoint or
file sha256, seed (and training seed), action, role, motion hash and video hash, and per
method source its checkpoints with their budgets and objective metrics; no paths and no
times, so two machines that build the same config write the same manifest. Sampling runs
on one torch thread, seeded.

Updating a study never loses answers: stimuli no longer in the build are deleted only
when no trial ever showed them; otherwise the build stops and changes nothing (build the
new set under a new slug, or put the source back).
"""

from __future__ import annotations

import difflib
import hashlib
import json
import os
import shutil
from collections import defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from django.db import transaction
from tqdm import tqdm

from motion import ops, perturb
from motion.formats import FormatError, load_motions, npz
from motion.motion import MotionError
from generation.sampling import SamplingError, choose
from rendering import VERSION as RENDERING_VERSION
from rendering import Framing, get_style, render_set
from studyapp.stimuli.catch_clips import CATCH_PER_BASE, catch_clips, prompt_catch_clips
from studyapp.survey.models import ScoringStandard, Stimulus, Study
from studyapp.stimuli.render_fanout import FanOutError, fan_out
from studyapp.stimuli.render_fanout import clean as clean_fanout
from studyapp.stimuli.clips import Clip, file_hash, register_clips
from studyapp.stimuli.config import ConfigError, StudyConfig, normalise_prompt, prompt_key
from studyapp.stimuli.sources import MethodSources

Role = Stimulus.Role
# Real clips drawn per action beyond the judged ones: a reference, the base of the
# examples, catch and anchor clips, and the base of the practice clips.
EXTRA_REAL = 3
# Joint jitter of the practice clips after the first (a real clip), as in perturb.
PRACTICE_NOISE = (0.02, 0.05, 0.1, 0.15, 0.2)


class BuildError(RuntimeError):
    """The build cannot go on (e.g. it would delete answered stimuli); nothing was changed."""


@dataclass
class BuildResult:
    study: Study | None
    manifest: Path
    entries: list[dict] = field(default_factory=list)
    rendered: int = 0  # clips rendered now (not taken from the cache)
    sampled: list[str] = field(default_factory=list)  # sources sampled now
    removed: int = 0  # stimuli deleted from the study
    unchanged: bool = False  # the study already held exactly these clips
    # What the build did that the config did not say (motions cut shorter, ...); the
    # command prints them.
    warnings: list[str] = field(default_factory=list)


def digest(value) -> str:
    return hashlib.sha256(json.dumps(value, sort_keys=True, default=str).encode()).hexdigest()


class Build:
    """One build of a config into ``folder`` (manifest) with caches in ``cache``."""

    def __init__(self, config: StudyConfig, folder, progress=None, log=None, cache=None,
                 workers=None):
        self.config = config
        self.workers = workers  # "celery", a number of processes, or None (STUDY_RENDER_WORKERS)
        self.folder = Path(folder)
        self.cache = Path(cache) if cache is not None else self.folder
        self.progress = progress  # callable(done, total, message), e.g. a background job's
        self.log = log or (lambda message: None)
        self._dataset = None
        self.bar = None
        self.kind = config.kind()
        self.methods = MethodSources(self)  # checkpoints, samples and metrics of method sources
        self._files = {}  # source name -> its file's motions, selected (read once per build)
        self._frames = None
        if config.prompts_shared:
            config.prompts = self.shared_prompts()

    # The dataset loads only when a cache misses: a no-op rebuild never reads it.
    @property
    def dataset(self):
        if self._dataset is None:
            from motion.datasets import get_dataset

            try:
                self._dataset = get_dataset(self.config.dataset, self.config.data_root)
            except KeyError as exc:
                raise ConfigError(f"dataset: {exc.args[0]}") from None
        return self._dataset

    def data_fields(self) -> dict:
        c = self.config
        fields = {"dataset": c.dataset, "subjects": c.subjects, "actions": c.actions,
                  "frames": c.frames, "fps": c.fps, "n": c.clips_per_source}
        if c.frames_auto:
            fields["frames"] = ["auto", self.clip_frames()]
        if c.prompts is not None:
            fields["prompts"] = c.prompts
        return fields

    def clip_frames(self) -> int:
        """Return the clips' length in frames: ``frames``; with ``frames: auto`` the longest
        length every file source's motions of the study's actions or prompts have (the
        dataset's clip length without file sources); else the dataset's clip length."""
        c = self.config
        if c.frames:
            return c.frames
        if not c.frames_auto:
            return self.dataset.clip_frames
        if self._frames is None:
            lengths = [m.frames for source in c.sources if source.kind == "file"
                       for m in self._shown(self.selected_file_motions(source))]
            self._frames = min(lengths) if lengths else self.dataset.clip_frames
        return self._frames

    def _shown(self, motions) -> list:
        """Return the motions a study of the config's prompts or actions can show."""
        c = self.config
        if c.prompts is not None:
            wanted = {normalise_prompt(p) for p in c.prompts}
            return [m for m in motions if m.text and normalise_prompt(m.text) in wanted]
        if c.actions is not None:
            return [m for m in motions if m.action in c.actions]
        return list(motions)

    def selected_file_motions(self, source) -> list:
        """Return a file source's motions at the study's rate, only the ``samples`` and
        ``repetitions`` it selects (read once per build)."""
        if source.name in self._files:
            return self._files[source.name]
        c = self.config
        options = {k: (str(c.path(v)) if k == "classes_path" else v)
                   for k, v in source.options.items()}
        fps = c.fps or self.dataset.clip_fps
        motions = list(self.file_motions(source, fps=fps, **options))
        for field_name, key in (("samples", "sample"), ("repetitions", "repetition")):
            chosen = getattr(source, field_name)
            if chosen is None:
                continue
            where = f"sources.{c.sources.index(source)}.{field_name} ({source.name})"
            have = sorted({m.meta[key] for m in motions if key in m.meta})
            if not have:
                raise ConfigError(
                    f"{where}: file {source.file!r} ({source.format}) does not number its "
                    f"motions' {field_name} (MDM's results.npy does); drop {field_name}, or "
                    f"split the file into one file per source")
            missing = [n for n in chosen if n not in have]
            if missing:
                raise ConfigError(
                    f"{where}: file {source.file!r} has {field_name} {_span(have)}; "
                    f"{', '.join(map(str, missing))} {'is' if len(missing) == 1 else 'are'} "
                    f"not among them; choose from those")
            motions = [m for m in motions if m.meta.get(key) in chosen]
        self._files[source.name] = motions
        return motions

    def shared_prompts(self) -> list[str]:
        """Return the prompts every file source has motions of (``prompts_from: sources``),
        in the first source's order; none shared is one error listing each source's."""
        files = [s for s in self.config.sources if s.kind == "file"]
        if not files:
            raise ConfigError("prompts_from: sources takes the prompts the file sources share; "
                              "this config has no file source (give prompts or prompts_from: "
                              "FILE)")
        texts = {s.name: list(dict.fromkeys(" ".join(m.text.split())
                                            for m in self.selected_file_motions(s) if m.text))
                 for s in files}
        common = set.intersection(*({normalise_prompt(t) for t in mine}
                                    for mine in texts.values()))
        shared = [t for t in texts[files[0].name] if normalise_prompt(t) in common]
        if not shared:
            listed = "; ".join(f"{name} has {len(mine)} ({', '.join(repr(t) for t in mine[:3])}"
                               f"{', ...' if len(mine) > 3 else ''})" for name, mine in texts.items())
            raise ConfigError(f"prompts_from: sources: the sources share no prompt: {listed}. "
                              f"Generate every source from the same prompts, or list the "
                              f"prompts to use (prompts: [...])")
        self.log(f"prompts_from: sources: {len(shared)} prompts every file source has")
        return shared

    def actions(self) -> list[str]:
        try:
            return choose(self.config.actions, self.dataset.actions(), "action",
                          f"dataset {self.config.dataset!r}")
        except SamplingError as exc:
            raise ConfigError(f"actions: {exc}") from None

    def roles(self) -> dict[str, int]:
        """Return the extra clips per action the study's type asks for."""
        c = self.config
        given = {name: value for name, value in c.study_options.items() if value is not None}
        return self.kind.stimulus_roles({**self.kind.defaults(len(c.sources)), **given,
                                         **c.type_options})

    def step(self, message: str, n: int = 1) -> None:
        self.bar.set_description_str(message[:40])
        self.bar.update(n)
        if self.progress:
            self.progress(self.bar.n, self.bar.total, message)

    def run(self, dry_run: bool = False) -> BuildResult:
        c = self.config
        if dry_run:
            return self.plan()
        self.folder.mkdir(parents=True, exist_ok=True)
        # One step per source sampled, one per clip rendered, one to register; clips
        # are counted once known (the dataset may not need loading at all).
        self.bar = tqdm(total=len(c.sources) + 3, desc="build_stimuli", unit="step",
                        dynamic_ncols=True, mininterval=1.0)
        result = BuildResult(None, self.folder / "manifest.json")
        try:
            groups = []
            for source in c.sources:
                motions, meta, fresh = self.source_motions(source)
                if fresh:
                    result.sampled.append(source.name)
                groups.append((source, motions, meta))
                self.step(f"sampled {source.name}")
            if c.prompts is None:
                base, framing = self.real_base()
                extras = self.extras(base) + catch_clips(self, groups, framing)
            else:
                same_skeleton(groups)
                # As with actions, real clips set the framing when there are any (a change
                # of a generated source then re-renders only its clips); else every source's.
                real = [m for source, motions, _ in groups if source.kind == "real"
                        for m in motions]
                framing = self.pooled_framing(real or [m for _, motions, _ in groups
                                                       for m in motions])
                extras = prompt_catch_clips(self, groups, framing)
            self.step("framing")
            result.warnings = cut_warnings(groups, self.clip_frames(),
                                           c.fps or getattr(self.dataset, "clip_fps", None))
            for warning in result.warnings:
                self.log(f"warning: {warning}")
            judged = [(m, meta) for _, motions, meta in groups for m in motions]
            self.bar.total += len(judged) + len(extras)
            self.bar.refresh()
            clips, entries, result.rendered = self.render(judged, extras, framing)
            self.step("registering")
            result.entries = entries
            result.study, result.removed, result.unchanged = self.register(clips)
            self.write_manifest(result.entries)
            self.step("manifest written")
        finally:
            self.bar.close()
        return result

    def _file_plan(self, source) -> str:
        """Return what a file source holds and what the build would take of it."""
        motions = self.selected_file_motions(source)
        shown = self._shown(motions)
        frames = self.clip_frames()
        lengths = sorted(m.frames for m in shown) or [0]
        texts = {normalise_prompt(m.text) for m in motions if m.text}
        what = (f"{len(motions)} motions, {len(texts)} prompts" if texts else
                f"{len(motions)} motions of {len({m.action for m in motions})} actions")
        longer = sum(n > frames for n in lengths)
        cut = f"; {longer} would be cut to {frames} frames" if longer else ""
        if longer and not self.config.frames_auto:
            cut += f" (frames: auto would take {lengths[0]}, the shortest)"
        return (f"{what}; {len(shown)} of them for this study's "
                f"{'prompts' if self.config.prompts is not None else 'actions'}, "
                f"{lengths[0]}-{lengths[-1]} frames{cut}")

    def plan(self) -> BuildResult:
        """Report what would be built, touching nothing."""
        for source in self.config.sources:
            missing = ([] if source.kind != "method" or source.checkpoint else
                       [seed for seed, done in self.methods.planned(source) if not done])
            todo = (f" (to train: {source.iters} iterations, {source.schedule} schedule, seed"
                    f"{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))})" if missing else "")
            if source.kind == "file":  # opened and read, as the build will
                todo = f" {source.file} ({source.format}): {self._file_plan(source)}"
            self.log(f"{source.name}: {source.kind}{todo}")
        counts = dict(self.roles())
        if counts.get(Role.CATCH):
            counts[Role.CATCH] = CATCH_PER_BASE * len(self.config.sources)
        roles = ", ".join(f"{n} {role}" for role, n in counts.items()) or "none"
        prompts = self.config.prompts
        per = "action" if prompts is None else "prompt"
        self.log(f"study {self.config.slug!r} ({self.config.study_type}"
                 f"{'' if prompts is None else f', {len(prompts)} prompts'}), style "
                 f"{self.config.style} at {self.config.size} px, extra clips per {per}: "
                 f"{roles}; manifest in {self.folder}, caches in {self.cache}")
        return BuildResult(Study.objects.filter(slug=self.config.slug).first(),
                           self.folder / "manifest.json")

    # --- motions -------------------------------------------------------------------

    def source_motions(self, source):
        """Return (motions, manifest fields, sampled now?) of one source, from the cache if there."""
        c = self.config
        meta = {"source": source.name, "seed": source.seed}
        keyed = {}
        if source.kind == "method":
            keyed["checkpoints"] = [t.sha256 for t in self.methods.trained(source)]
        elif source.kind == "file":
            path = c.path(source.file)
            if not path.is_file() and not path.is_dir():
                raise ConfigError(f"sources: file {source.file!r} of source {source.name!r} is not "
                                  f"there (looked in {path}); fix the path")
            meta["file"] = file_hash(path) if path.is_file() else digest(sorted(
                (p.name, file_hash(p)) for p in path.iterdir() if p.is_file()))
            extra = source.options.get("classes_path")
            if extra:
                meta["classes"] = file_hash(c.path(extra))
        if len(keyed.get("checkpoints", ())) == 1:  # one checkpoint: keyed as before seeds
            keyed = {"checkpoint": keyed["checkpoints"][0]}
        key = digest({"source": source.section(), "data": self.data_fields(), **meta,
                      **keyed})[:16]
        cached = self.cache / "motions" / f"{source.name}-{key}.npz"
        trained = cached.with_suffix(".json")  # each method motion's training seed and checkpoint
        if cached.is_file() and (source.kind != "method" or trained.is_file()):
            motions = npz.load(cached)
            if source.kind == "method":
                seeds = json.loads(trained.read_text())
                motions = [m.with_joints(m.joints, meta={**m.meta, "training_seed": seed,
                                                         "checkpoint": sha})
                           for m, seed, sha in zip(motions, seeds["training_seed"],
                                                   seeds["checkpoint"])]
            return motions, meta, False
        motions = self.sample(source)
        npz.save(cached, motions)
        if source.kind == "method":
            _write_if_changed(trained, json.dumps({
                key: [m.meta.get(key) for m in motions] for key in ("training_seed", "checkpoint")}))
        return motions, meta, True

    def sample(self, source, n: int | None = None) -> list:
        """Return ``n`` motions per action of ``source`` (default ``clips_per_source``)."""
        c = self.config
        if c.prompts is not None:
            motions = self.prompt_motions(source)
            return [m.with_joints(m.joints, source=source.name, meta=dict(m.meta)) for m in motions]
        n = n or c.clips_per_source
        frames = self.clip_frames()
        if source.kind == "real":
            from generation.sampling import sample_real

            motions = sample_real(self.dataset, self.actions(), n, frames, source.seed, c.fps,
                                  c.subjects)
        elif source.kind == "method":
            motions = self.methods.sample(source, self.actions(), n, frames)
            if c.fps:
                motions = [ops.resample(m, c.fps) for m in motions]
        else:
            loaded = self.selected_file_motions(source)
            motions = []
            for action in self.actions():
                mine = [m for m in loaded if m.action == action][:n]
                motions.extend(_cut(m, frames) for m in mine)
            if not motions:
                raise ConfigError(f"sources: file {source.file!r} has no motions of the actions "
                                  f"{', '.join(self.actions())}; set the actions, or the file's "
                                  f"'action' option")
        return [m.with_joints(m.joints, source=source.name, meta=dict(m.meta)) for m in motions]

    def file_motions(self, source, **options) -> list:
        """Return the motions of a file source; a file that cannot be read (or that holds
        anything but data) is a :class:`ConfigError` naming the source."""
        path = self.config.path(source.file)
        if not path.is_file() and not path.is_dir():
            raise ConfigError(f"sources: file {source.file!r} of source {source.name!r} is not "
                              f"there (looked in {path}); fix the path")
        try:
            return load_motions(path, source.format, **options)
        except (FormatError, MotionError) as exc:
            raise ConfigError(f"sources: file {source.file!r} of source {source.name!r}: "
                              f"{exc}") from None

    def prompt_motions(self, source) -> list:
        """Return ``clips_per_source`` motions of ``source`` for each prompt, in prompt order:
        a file's motions whose text is the prompt, or real takes whose caption is."""
        c = self.config
        where = f"sources.{c.sources.index(source)} ({source.name})"
        frames = self.clip_frames()
        fps = c.fps or self.dataset.clip_fps
        if source.kind == "real":
            if not hasattr(self.dataset, "takes_for"):  # datasets with captions have it
                raise ConfigError(
                    f"{where}: real clips for prompts come from a dataset with captions in "
                    f"HumanML3D's layout (humanml3d, kit_ml); dataset {c.dataset!r} has none. Set "
                    f"dataset (and data_root), or give real clips as a file source (import_motions "
                    f"HumanML3D/ --format humanml3d --source real --out real.npz)")
            # As takes_for(prompt) does, for every prompt at once (the dataset is read once):
            # a take per caption, its text the caption.
            wanted = {normalise_prompt(p) for p in c.prompts}
            takes, known = [], []
            for take in self.dataset.load_takes().motions:
                for caption in take.meta.get("captions", []):
                    known.append(caption)
                    if normalise_prompt(caption) in wanted:
                        takes.append(ops.resample(take.with_joints(
                            take.joints, text=caption, meta=dict(take.meta)), fps))
            rng = np.random.default_rng(source.seed)
        else:
            takes = list(self.selected_file_motions(source))
            known = [m.text for m in takes if m.text]
            rng = None  # a file's motions are taken in its order
        return motions_for_prompts(c.prompts, takes, c.clips_per_source, frames, where, known,
                                   rng)

    def pooled_framing(self, motions) -> Framing:
        """Return one framing fitted to ``motions`` (a prompts study's real clips, or all its
        judged clips when it has no real data), in the renderer's frame as render_set draws
        them."""
        style = get_style(self.config.style)
        return Framing.from_motions([ops.canonical(m, style.dims) for m in motions],
                                    pad=style.pad)

    def real_base(self):
        """Return real clips (n + EXTRA_REAL per action) and the framing fitted to them, cached."""
        c = self.config
        key = digest({"data": self.data_fields(), "seed": c.seed, "style": c.style,
                      "size": c.size, "extra": EXTRA_REAL, "rendering": RENDERING_VERSION})[:16]
        cached = self.cache / "motions" / f"_real-{key}.npz"
        framing_file = self.cache / "motions" / f"_framing-{key}.json"
        if cached.is_file() and framing_file.is_file():
            return npz.load(cached), Framing(**_framing_fields(json.loads(framing_file.read_text())))
        from generation.sampling import sample_real

        frames = self.clip_frames()
        base = sample_real(self.dataset, self.actions(), c.clips_per_source + EXTRA_REAL,
                           frames, c.seed, c.fps, c.subjects)
        style = get_style(c.style)
        # Fitted in the renderer's frame (z up, metres), as render_set draws them.
        framing = Framing.from_motions([ops.canonical(m, style.dims) for m in base],
                                       pad=style.pad)
        npz.save(cached, base)
        framing_file.parent.mkdir(parents=True, exist_ok=True)
        framing_file.write_text(json.dumps(asdict(framing), sort_keys=True))
        return base, framing

    def extras(self, base) -> list[tuple]:
        """Return ``(motion, role, score)`` of the clips the study type asks for beyond the
        judged ones, made from real clips not judged (practice: for the first action only;
        catch clips: :func:`studyapp.stimuli.catch_clips.catch_clips`)."""
        roles = self.roles()
        if not roles:
            return []
        c = self.config
        n = c.clips_per_source
        per = n + EXTRA_REAL
        rng = np.random.default_rng(c.seed + 1)
        out = []
        for start in range(0, len(base), per):
            group = base[start:start + per]
            reference, root, practice = group[n], group[n + 1], group[n + 2]
            if roles.get(Role.REFERENCE):
                out.append((reference, Role.REFERENCE, None))
            if roles.get(Role.EXAMPLE):
                for score, motion in perturb.standard_examples(root, rng).items():
                    out.append((motion, Role.EXAMPLE, score))
            if roles.get(Role.CATCH):
                # The draw the one shaken catch clip took before catch clips came as a
                # family (catch_clips.py): anchors and practice clips stay as built before.
                rng.normal(size=root.joints.shape)
            if roles.get(Role.ANCHOR):
                out.append((perturb.low_anchor(root, rng), Role.ANCHOR, None))
            if roles.get(Role.PRACTICE) and start == 0:
                for k in range(roles[Role.PRACTICE]):
                    noise = PRACTICE_NOISE[(k - 1) % len(PRACTICE_NOISE)] if k else 0.0
                    out.append((perturb.jitter(practice, noise, rng, "practice_clip"),
                                Role.PRACTICE, None))
        return out

    # --- renders -------------------------------------------------------------------

    def render(self, judged, extras, framing):
        """Render what the cache lacks; return the clips and manifest entries in build
        order, and the count rendered now."""
        c = self.config
        folder = self.cache / "renders"
        index_file = folder / "index.json"
        index = json.loads(index_file.read_text()) if index_file.is_file() else {}
        settings = {"style": c.style, "size": c.size, "framing": asdict(framing),
                    "rendering": RENDERING_VERSION}
        items = [(m, {"role": Role.JUDGED, **meta, "checkpoint": m.meta.get("checkpoint"),
                      "training_seed": m.meta.get("training_seed")}) for m, meta in judged]
        items += [(m, {"role": role, "score": score, "source": m.source, "seed": c.seed})
                  for m, role, score in extras]
        keys = [digest({"motion": m.content_hash(), **settings}) for m, _ in items]
        missing = [i for i, key in enumerate(keys) if key not in index
                   or not (folder / f"{index[key]['video_hash']}.mp4").is_file()]
        self.step("renders cached", len(items) - len(missing))
        workers = render_workers(len(missing), self.workers) if missing else 1
        if workers == "celery":
            self.render_by_workers(items, keys, missing, folder, framing, index, index_file)
        elif missing:
            incoming = folder / f".incoming-{c.slug}"
            shutil.rmtree(incoming, ignore_errors=True)
            report = render_set(
                [items[i][0] for i in missing], incoming, style=c.style, size=c.size,
                framing=framing, progress=False, workers=workers,
                on_clip=lambda i: self.step(f"rendered {items[missing[i]][0].source}"))
            if report.failures:
                raise BuildError(f"clips failed to render in the {c.style!r} style: "
                                 f"{report.failures}")
            for done in report.clips:
                for path in (Path(done.video), Path(done.poster)):
                    target = folder / path.name
                    if not target.is_file():  # two clips may share one video
                        path.replace(target)
                index[keys[missing[done.index]]] = {"video_hash": done.video_hash,
                                                    "duration": done.duration}
            shutil.rmtree(incoming, ignore_errors=True)
            _write_if_changed(index_file, json.dumps(index, sort_keys=True, indent=1))
        payloads = self.payloads([m for m, _ in items], framing, folder)
        clips, entries = [], []
        for (motion, spec), key, payload in zip(items, keys, payloads):
            done = index[key]
            clip = Clip(
                action=motion.action, source=spec["source"], role=spec["role"],
                score=spec.get("score"), prompt=getattr(motion, "text", "") or "",
                motion_hash=motion.content_hash(), video_hash=done["video_hash"],
                video=folder / f"{done['video_hash']}.mp4",
                poster=folder / f"{done['video_hash']}.png", duration=done["duration"],
                motion=payload, checkpoint=spec.get("checkpoint") or "",
                training_seed=spec.get("training_seed"),
            )
            clips.append(clip)
            entry = {**spec, "action": clip.action, "prompt": clip.prompt or None,
                     "motion_hash": clip.motion_hash, "video_hash": clip.video_hash}
            entries.append({k: entry[k] for k in ("source", "checkpoint", "file", "seed",
                                                  "training_seed", "action", "prompt", "role",
                                                  "score", "motion_hash", "video_hash")
                            if entry.get(k) is not None})
        return clips, entries, len(missing)

    def render_by_workers(self, items, keys, missing, folder, framing, index, index_file):
        """Render the ``missing`` clips by Celery render workers (survey.render_fanout)
        into the shared renders ``folder``; add them to ``index`` and write it."""
        c = self.config
        at = defaultdict(list)  # key -> the items it draws (two items may share a motion)
        for i in missing:
            at[keys[i]].append(i)

        def finished(key):
            for i in at[key]:
                self.step(f"rendered {items[i][0].source}")

        try:
            records, failures = fan_out([(key, items[i[0]][0]) for key, i in at.items()],
                                        folder, c.style, c.size, framing, on_clip=finished,
                                        say=self.log)
        except FanOutError as exc:
            raise BuildError(str(exc)) from None
        if failures:
            raise BuildError(f"clips failed to render in the {c.style!r} style: "
                             f"{[(at[k][0], message) for k, message in failures.items()]}")
        for key, record in records.items():
            index[key] = {"video_hash": record["video_hash"], "duration": record["duration"]}
        _write_if_changed(index_file, json.dumps(index, sort_keys=True, indent=1))
        clean_fanout(folder, list(records))

    def payloads(self, motions, framing, folder) -> list:
        """Write the in-browser player's payloads (render.player: webgl), or Nones."""
        if self.config.player != "webgl":
            return [None] * len(motions)
        from rendering.player import write_payloads

        placed = [ops.canonical(m, 3) for m in motions]  # as render_set draws them
        # Filmed as their videos are (the size and style's reach decide each clip's shot).
        written = write_payloads(placed, folder / "payloads", framing, self.config.size,
                                 self.config.style)
        return [path for path, _ in written]

    # --- study and manifest ---------------------------------------------------------

    def study_fields(self) -> dict:
        c = self.config
        fields = self.kind.defaults(len(c.sources))
        fields.update({k: v for k, v in c.study_options.items() if v is not None})
        fields["dataset"] = c.dataset
        fields["options"] = dict(c.type_options)
        fields["player"] = "" if c.player == "video" else get_style(c.style).player_figure
        if c.prompts is not None and not fields.get("instructions"):
            draft = Study(study_type=c.study_type, options=fields["options"],
                          clips_per_trial=fields.get("clips_per_trial",
                                                     self.kind.default_clips_per_trial))
            fields["instructions"] = self.kind.prompt_instructions(draft)
        return fields

    def register(self, clips):
        """Create or update the study to hold exactly these clips; return (study, removed,
        unchanged)."""
        c = self.config
        wanted = {clip.video_hash for clip in clips}
        with transaction.atomic():
            study = Study.objects.filter(slug=c.slug).first()
            changed = study is None
            if study is None:
                study = Study.objects.create_study(c.study_type, c.slug, c.title,
                                                   **self.study_fields())
            elif study.study_type != c.study_type:
                raise BuildError(f"study {c.slug!r} is a {study.study_type} study, not "
                                 f"{c.study_type}; pick another slug")
            else:
                changes = {"title": c.title, **self.study_fields()}
                if "crowd" in changes:
                    # Settings stored since (e.g. by `prolific create`: its codes and study
                    # id) are kept; the config's own settings win.
                    changes["crowd"] = {**(study.crowd or {}), **changes["crowd"]}
                if any(getattr(study, k) != v for k, v in changes.items()):
                    changed = True
                    for name, value in changes.items():
                        setattr(study, name, value)
                    study.full_clean()
                    study.save()
            have = dict(study.stimuli.values_list("video_hash", "role"))
            if have == {clip.video_hash: clip.role for clip in clips} and not changed:
                return study, 0, True
            stale = study.stimuli.exclude(video_hash__in=wanted)
            shown = stale.filter(items__isnull=False).distinct()
            if shown.exists():
                sources = sorted({s.source for s in shown})
                raise BuildError(
                    f"study {c.slug!r}: {shown.count()} stimuli of {', '.join(sources)} are no "
                    f"longer in the config but participants have seen them; answers are never "
                    f"deleted. Put those sources back, or build under a new slug"
                )
            removed = stale.count()
            if removed:
                ScoringStandard.objects.filter(stimulus__in=stale).delete()
                stale.delete()
            try:
                stimuli = register_clips(study, clips)
            except ValueError as exc:  # two sources gave the same video
                raise BuildError(f"{exc}; give the sources different motions") from None
            self.kind.after_register(study, clips, stimuli)
        return study, removed, False

    def write_manifest(self, entries) -> None:
        c = self.config
        manifest = {"slug": c.slug, "study_type": c.study_type, "dataset": c.dataset,
                    "style": c.style, "size": c.size, "clips": entries}
        if any(source.kind == "method" for source in c.sources):
            manifest["sources"], manifest["metrics"] = self.methods.manifest(c.sources)
        _write_if_changed(self.folder / "manifest.json", json.dumps(manifest, indent=1) + "\n")


def same_skeleton(groups) -> None:
    """Refuse sources of a prompts study whose figures differ (their skeleton would tell
    participants which clip is whose)."""
    first = None
    for source, motions, _ in groups:
        skeletons = sorted({m.skeleton for m in motions})
        if first is None:
            first = (source.name, skeletons)
        elif skeletons != first[1]:
            raise ConfigError(
                f"sources: {source.name!r} has skeleton {', '.join(skeletons)} but "
                f"{first[0]!r} has {', '.join(first[1])}; the figure would tell participants "
                f"the sources apart. Compare sources of one skeleton (models of one dataset: "
                f"HumanML3D's smpl22 or KIT-ML's kit21)")


def motions_for_prompts(prompts, motions, n: int, frames: int, where: str, known=(),
                        rng=None) -> list:
    """Return ``n`` motions per prompt, prompt by prompt, cut to ``frames`` frames.

    A motion is a prompt's when its ``text`` is the prompt (ignoring case, spacing and a
    final full stop); motions shorter than ``frames`` are not used. ``rng`` draws the
    motions (default: the first ``n`` in order). Each returned motion's ``action`` is the
    prompt's key (:func:`prompt_key`), its ``text`` the prompt as the config gives it
    (one text per trial, whichever source a clip comes from) and ``meta["caption"]`` its
    own text. Raise :class:`ConfigError` naming the prompt, the source (``where``) and
    the closest of the ``known`` texts when a prompt has too few motions.
    """
    by_text = defaultdict(list)
    for motion in motions:
        if motion.text:
            by_text[normalise_prompt(motion.text)].append(motion)
    texts = list(dict.fromkeys(t for t in known if t)) or [m.text for m in motions if m.text]
    out = []
    for prompt in prompts:
        found = by_text.get(normalise_prompt(prompt), [])
        if not found:
            spelled = {normalise_prompt(t): t for t in reversed(texts)}
            close = difflib.get_close_matches(normalise_prompt(prompt), list(spelled), n=3,
                                              cutoff=0.6)
            if close:
                hint = "close matches: " + "; ".join(repr(spelled[t]) for t in close)
            elif texts:
                hint = f"it has {len(texts)} other prompts, e.g. {texts[0]!r}"
            else:
                hint = "it has no prompts at all (import its motions with their texts)"
            raise ConfigError(f"prompts: {where} has no motion for prompt {prompt!r}; {hint}. Fix "
                              f"the prompt (or drop it), or give that source motions of it")
        usable = [m for m in found if m.frames >= frames]
        if len(usable) < n:
            longest = max(m.frames for m in found)
            fix = (f"set frames to {longest} or less" if not usable else
                   "lower clips_per_source (or frames)")
            raise ConfigError(f"prompts: {where} has {len(usable)} motion(s) of at least {frames} "
                              f"frames for prompt {prompt!r} (clips_per_source is {n}; its "
                              f"longest has {longest}); {fix}")
        if rng is None:
            chosen = usable[:n]
        else:
            chosen = [usable[i] for i in sorted(rng.choice(len(usable), n, replace=False))]
        for motion in chosen:
            cut = _cut(motion, frames)
            out.append(cut.with_joints(cut.joints, action=prompt_key(prompt), text=prompt,
                                       meta={**cut.meta, "caption": motion.text}))
    return out


def _cut(motion, frames: int):
    """Return ``motion``'s first ``frames`` frames; one cut shorter records its length
    (``meta["cut_from"]``), which the build reports."""
    if motion.frames <= frames:
        return motion
    cut = ops.trim(motion, 0, frames)
    return cut.with_joints(cut.joints, meta={**cut.meta, "cut_from": motion.frames})


def _span(numbers) -> str:
    numbers = sorted(numbers)
    if numbers == list(range(numbers[0], numbers[-1] + 1)) and len(numbers) > 2:
        return f"{numbers[0]}-{numbers[-1]}"
    return ", ".join(map(str, numbers))


def cut_warnings(groups, frames: int, fps) -> list[str]:
    """Return one sentence per source whose motions were cut shorter than they are."""
    out = []
    for source, motions, _ in groups:
        lengths = [m.meta["cut_from"] for m in motions if m.meta.get("cut_from")]
        if not lengths:
            continue
        seconds = f" ({frames / float(fps):.1f} s)" if fps else ""
        low, high = min(lengths), max(lengths)
        out.append(f"{source.name}: {len(lengths)} of its {len(motions)} motions were cut to "
                   f"{frames} frames{seconds} from {low if low == high else f'{low}-{high}'}; "
                   f"set frames: auto for the longest length every source has, or frames: N")
    return out


def _framing_fields(raw: dict) -> dict:
    raw["target"] = tuple(raw["target"])
    return raw


def _write_if_changed(path: Path, text: str) -> bool:
    if path.is_file() and path.read_text() == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)
    return True


def default_folders(config: StudyConfig, out=None, cache=None) -> tuple[Path, Path]:
    """Return the study's build folder and the cache folder: ``<var>/stimuli/<slug>`` and
    ``<var>/stimuli/cache`` (shared by every study), or ``out`` for both when given."""
    from django.conf import settings

    root = Path(settings.VAR_DIR) / "stimuli"
    folder = Path(out) if out else root / config.slug
    return folder, Path(cache) if cache else (folder if out else root / "cache")


# Fewer clips than this render in the build's own process: starting worker processes
# (each imports the renderer) costs more than it saves.
PARALLEL_FROM = 12


def render_workers(n_clips: int, given=None) -> int | str:
    """Return how many processes of this machine render ``n_clips``, or ``"celery"`` to
    send them to Celery render workers: ``given`` (the command's ``--workers``), else
    ``STUDY_RENDER_WORKERS`` if set, else one per CPU core (at most 4) once there are
    ``PARALLEL_FROM`` clips."""
    name = "--workers" if given not in (None, "") else "STUDY_RENDER_WORKERS"
    given = str(given if given not in (None, "") else
                os.environ.get("STUDY_RENDER_WORKERS", "")).strip()
    if given.lower() == "celery":
        return "celery"
    if given:
        try:
            return max(1, int(given))
        except ValueError:
            raise BuildError(f"{name}={given!r} is not a whole number or 'celery'; set it to "
                             f"how many processes of this machine render clips, e.g. 2, or "
                             f"to celery for Celery render workers") from None
    if n_clips < PARALLEL_FROM:
        return 1
    return max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                      else (os.cpu_count() or 1)))


def build_stimuli(config: StudyConfig, folder, progress=None, log=None,
                  dry_run: bool = False, cache=None, workers=None) -> BuildResult:
    """Build ``config`` into ``folder`` (caches in ``cache``, default ``folder``); see the
    module docstring. ``workers`` renders in that many processes here, or by Celery render
    workers with ``"celery"`` (default: ``STUDY_RENDER_WORKERS``, else one per core)."""
    return Build(config, folder, progress, log, cache, workers).run(dry_run)
