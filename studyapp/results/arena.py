"""Sources joining and leaving an arena (:mod:`studyapp.participation.arena`): ``arena add``
and ``arena retire``.

A source is added as the study's build would have built it beside the others: its file
is read by the safe importers (:func:`motion.formats.load_motions` through the build's
file source), checked to hold a motion of every prompt of the arena (all missing prompts
named at once), cut to the arena's clip length, rendered in the study's style, size and
framing (the framing the build fitted: to its real clips, or to the first sources' clips
when it had none) with the same padded byte budgets, given its catch clips where the
study has catch trials, and registered. The new clips must have the byte sizes the
arena's clips of their length have, and the blindness audit
(:func:`studyapp.results.audit.audit_study`) runs on the study with them; if either
fails, nothing is registered. The adaptive design's distribution is then computed again,
so the next participants' pairs aim at the new source, whose posterior is the widest.

The build folder keeps the config as built (``config.yaml``, written by
``build_stimuli``); the added source is appended to it, with the arena's prompts and clip
length written out, and its clips to ``manifest.json``, so ``bundle`` and a rebuild see
the arena as it stands.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import asdict
from pathlib import Path

import yaml
from django.core.files.storage import default_storage
from django.db import transaction
from django.utils import timezone
from tqdm import tqdm

from rendering import Framing

from studyapp.participation.arena import is_arena, retired
from studyapp.results.adaptive import recompute
from studyapp.results.audit import AuditUnavailable, audit_study, passed, view_fetcher
from studyapp.stimuli.build import Build, default_folders, same_skeleton
from studyapp.stimuli.catch_clips import prompt_catch_clips
from studyapp.stimuli.clips import register_clips
from studyapp.stimuli.config import ConfigError, normalise_prompt, parse
from studyapp.survey.models import Stimulus, Study

Role = Stimulus.Role
SHOWN_MISSING = 10  # missing prompts named in the error; the rest are counted


class ArenaError(RuntimeError):
    """The arena cannot take this change; nothing was changed."""


def arena_of(slug: str) -> Study:
    study = Study.objects.filter(slug=slug).first()
    if study is None:
        raise ArenaError(f"no study {slug!r}; `manage.py studies` lists them")
    if not is_arena(study):
        raise ArenaError(f"study {slug!r} is not an arena; give its config study.arena: {{}} "
                         f"(with design: adaptive) and build it again")
    return study


def sources_of(study) -> list[str]:
    """Return every source with judged clips in the study, retired ones included."""
    return sorted(set(Stimulus.objects.judged().filter(study=study)
                      .values_list("source", flat=True)))


def prompts_of(study) -> list[str]:
    """Return the arena's prompts, in the order their clips were registered."""
    rows = Stimulus.objects.judged().filter(study=study).order_by("pk").values_list("prompt", flat=True)
    return list(dict.fromkeys(p for p in rows if p))


def retire(study, name: str) -> dict:
    """Stop showing ``name``'s clips in new trials; its clips, answers and scores stay."""
    if name not in sources_of(study):
        raise ArenaError(f"arena {study.slug!r} has no source {name!r}; its sources are "
                         f"{', '.join(sources_of(study))}")
    if name in retired(study):
        raise ArenaError(f"source {name!r} of arena {study.slug!r} is retired already")
    left = [s for s in sources_of(study) if s not in retired(study) and s != name]
    if len(left) < 2:
        raise ArenaError(f"retiring {name!r} would leave arena {study.slug!r} with "
                         f"{len(left)} source to show; add a source first (arena add)")
    with transaction.atomic():
        locked = Study.objects.lock(study.pk)
        state = dict(locked.arena_state or {})
        state["retired"] = {**(state.get("retired") or {}), name: timezone.now().isoformat()}
        state["changed_at"] = timezone.now().isoformat()  # the leaderboard is out of date
        Study.objects.filter(pk=study.pk).update(arena_state=state)
        study.arena_state = state
    _recompute_design(study)
    return state["retired"]


def _recompute_design(study) -> None:
    """Compute the adaptive design's distribution now, over the sources shown."""
    recompute(study)


def _build_config(study, folder: Path, extra: dict | None = None):
    """Return the study's config as built (``config.yaml`` in ``folder``), its prompts
    fixed to the arena's and ``extra`` a source appended; and the raw mapping."""
    kept = folder / "config.yaml"
    if not kept.is_file():
        raise ArenaError(f"arena {study.slug!r}: its build folder {folder} has no config.yaml "
                         f"(build_stimuli keeps the config as built there); give the folder the "
                         f"study was built into with --out")
    raw = yaml.safe_load(kept.read_text())
    if raw.get("slug") != study.slug:
        raise ArenaError(f"{kept} builds study {raw.get('slug')!r}, not {study.slug!r}; give "
                         f"the arena's own build folder with --out")
    raw.pop("prompts_from", None)
    raw["prompts"] = prompts_of(study)
    if extra is not None:
        raw["sources"] = list(raw["sources"]) + [extra]
    return parse(raw, folder), raw


def add(study, file, name: str, format: str = "auto", out=None, cache=None,
        audit: str | None = "deep", log=None) -> dict:
    """Add the motions of ``file`` as source ``name`` of arena ``study`` (see the module
    docstring); return what was done."""
    log = log or (lambda message: None)
    file = Path(file).resolve()
    if not file.exists():
        raise ArenaError(f"--file {file}: no such file; give the model's results.npy (or any "
                         f"file import_motions reads)")
    if not name or not name.replace("-", "").replace("_", "").isalnum() or len(name) > 100:
        raise ArenaError(f"--name {name!r}: use letters, digits, - and _ (at most 100)")
    if name in sources_of(study):
        raise ArenaError(f"arena {study.slug!r} has a source {name!r} already"
                         f"{' (retired)' if name in retired(study) else ''}; pick another name")
    prompts = prompts_of(study)
    if not prompts:
        raise ArenaError(f"arena {study.slug!r} has no prompts: an arena is a study of text "
                         f"prompts (prompts: or prompts_from: in its config)")
    probe_config, _ = _build_config(study, _folders(study, out, cache)[0])
    folder, cache_folder = _folders(study, out, cache, probe_config)
    before = Build(probe_config, folder, log=log, cache=cache_folder)
    frames = before.clip_frames()
    entry = {"name": name, "file": str(file), "format": format}
    try:
        config, raw = _build_config(study, folder, entry)
    except ConfigError as exc:
        raise ArenaError(str(exc)) from None
    config.frames, config.frames_auto = frames, False
    build = Build(config, folder, log=log, cache=cache_folder)
    build.bar = tqdm(total=0, disable=True)
    new = config.sources[-1]
    try:
        loaded = build.selected_file_motions(new)
    except ConfigError as exc:
        raise ArenaError(str(exc)) from None
    have = {normalise_prompt(m.text) for m in loaded if m.text}
    missing = [p for p in prompts if normalise_prompt(p) not in have]
    if missing:
        named = "; ".join(repr(p) for p in missing[:SHOWN_MISSING])
        more = f" and {len(missing) - SHOWN_MISSING} more" if len(missing) > SHOWN_MISSING else ""
        raise ArenaError(
            f"--file {file}: no motion for {len(missing)} of the arena's {len(prompts)} "
            f"prompts: {named}{more}. Generate motions of every prompt (`manage.py arena "
            f"prompts --study {study.slug}` lists them, one a line, as MDM's --input_text "
            f"reads them) and add the file again")
    groups = []
    for source in config.sources[:-1]:
        try:
            motions, meta, _ = build.source_motions(source)
        except ConfigError as exc:
            raise ArenaError(f"{exc} (the arena's first sources are read again for their "
                             f"skeleton and framing)") from None
        groups.append((source, motions, meta))
    kept = (study.arena_state or {}).get("framing")
    if kept:  # the framing of the first add, kept: later adds draw exactly alike
        framing = Framing(**{**kept, "target": tuple(kept["target"])})
    else:
        real = [m for source, motions, _ in groups if source.kind == "real" for m in motions]
        framing = build.pooled_framing(real or [m for _, motions, _ in groups for m in motions])
    try:
        motions, meta, _ = build.source_motions(new)
    except ConfigError as exc:
        raise ArenaError(f"{exc} (the arena's clips are {frames} frames: give motions of at "
                         f"least that length)") from None
    same_skeleton(groups + [(new, motions, meta)])
    extras = prompt_catch_clips(build, [(new, motions, meta)], framing)
    clips, entries, rendered = build.render([(m, meta) for m in motions], extras, framing)
    _same_sizes(study, clips)
    with transaction.atomic():
        stimuli = register_clips(study, clips)
        outcome = None
        if audit:
            try:
                outcome = audit_study(study, view_fetcher(), audit)
            except AuditUnavailable as exc:
                raise ArenaError(f"the blindness audit could not run: {exc}") from None
            if not passed(outcome):
                failed = ", ".join(k for k, part in outcome.items() if not part["passed"])
                raise ArenaError(f"source {name!r}: with its clips the arena's clips can be told "
                                 f"apart by what is sent ({failed}); nothing was added")
        locked = Study.objects.lock(study.pk)
        state = dict(locked.arena_state or {})
        state["added"] = {**(state.get("added") or {}), name: {
            "at": timezone.now().isoformat(), "file_sha256": meta.get("file"),
            "clips": sum(s.role == Role.JUDGED for s in stimuli)}}
        state.setdefault("framing", asdict(framing))
        state["changed_at"] = timezone.now().isoformat()  # the leaderboard is out of date
        Study.objects.filter(pk=study.pk).update(arena_state=state)
        study.arena_state = state
    _keep(folder, raw, frames, entries)
    _recompute_design(study)
    return {"source": name, "clips": len(clips), "rendered": rendered,
            "judged": sum(c.role == Role.JUDGED for c in clips), "prompts": len(prompts),
            "audit": outcome}


def _folders(study, out, cache, config=None) -> tuple[Path, Path]:
    class Slug:  # default_folders reads the slug only
        slug = study.slug

    return default_folders(config or Slug, out, cache)


def _same_sizes(study, clips) -> None:
    """Refuse new clips whose byte sizes differ from the arena's clips of their length."""
    sizes = {}
    for stimulus in Stimulus.objects.filter(study=study).exclude(video=""):
        try:
            sizes.setdefault(round(stimulus.duration, 3), Counter())[default_storage.size(stimulus.video)] += 1
        except OSError:
            continue
    for clip in clips:
        known = sizes.get(round(clip.duration, 3))
        size = Path(clip.video).stat().st_size
        if known and size not in known:
            raise ArenaError(f"the new clips are {size} bytes but the arena's clips of "
                             f"{clip.duration:g} s are {', '.join(map(str, known))}: they would "
                             f"tell the source; build with the study's render settings")


def _keep(folder: Path, raw: dict, frames: int, entries: list) -> None:
    """Write the config as it now stands and the new clips into the build folder."""
    raw = {**raw, "frames": frames}
    (folder / "config.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    manifest_file = folder / "manifest.json"
    if manifest_file.is_file():
        manifest = json.loads(manifest_file.read_text())
        known = {e["video_hash"] for e in manifest.get("clips", [])}
        manifest["clips"] = manifest.get("clips", []) + [e for e in entries
                                                         if e["video_hash"] not in known]
        manifest_file.write_text(json.dumps(manifest, indent=1) + "\n")


