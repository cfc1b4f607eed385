"""The motions a study showed, read back from its build: what ``correlate`` measures.

A build (:mod:`studyapp.stimuli.build`) keeps each source's motions in its cache
(``<cache>/motions/<source>-<key>.npz``) and lists every clip in the study's
``manifest.json`` (source, checkpoint or file hash, role, motion hash). Each judged
stimulus of the study stores its clip's motion hash, so the very motions participants
judged are found again by hash in those files; nothing is sampled anew.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path


class MotionsUnavailable(ValueError):
    """A study's motions cannot be read back (no manifest, no method source, a cache miss)."""


@dataclass
class StudyMotions:
    """The judged motions of a study, by source: ``generated`` (methods and imported
    files, with how each was made) and the names of its real sources."""

    generated: dict  # source -> list of Motion, in the study's stimulus order
    kinds: dict  # source -> "method" or "file"
    real: list
    manifest: Path
    cache: list


def default_paths(slug: str) -> tuple[Path, Path]:
    """Return where ``build_stimuli`` puts a study's manifest and the shared cache by default."""
    from django.conf import settings

    root = Path(settings.VAR_DIR) / "stimuli"
    return root / slug / "manifest.json", root / "cache"


def source_kinds(manifest: dict) -> dict[str, str]:
    """Return ``source -> method | file | real`` for the judged clips of a manifest."""
    kinds = {}
    for entry in manifest.get("clips", []):
        if entry.get("role", "judged") != "judged":
            continue
        kind = "method" if "checkpoint" in entry else "file" if "file" in entry else "real"
        kinds.setdefault(entry["source"], kind)
    return kinds


def study_motions(study, manifest=None, cache=None) -> StudyMotions:
    """Return the judged motions of ``study``'s generated sources, read from its build.

    ``manifest`` is the study's ``manifest.json`` (default: where ``build_stimuli`` writes
    it); ``cache`` the build's cache folder (default: the manifest's folder, then the
    shared cache). Raise :class:`MotionsUnavailable` saying which source lacks what and
    how to get it back.
    """
    from motion.formats import npz

    default_manifest, default_cache = default_paths(study.slug)
    manifest = Path(manifest) if manifest else default_manifest
    rebuild = (f"rebuild it with `manage.py build_stimuli CONFIG` (the config that built study "
               f"{study.slug!r}: the same config samples the same motions again and keeps the "
               f"answers); a study built with --out DIR has its manifest and cache there: pass "
               f"--manifest DIR/manifest.json --cache DIR")
    if not manifest.is_file():
        raise MotionsUnavailable(f"study {study.slug!r} has no build manifest at {manifest}; "
                                 f"{rebuild}")
    try:
        listed = json.loads(manifest.read_text())
    except (OSError, ValueError) as exc:
        raise MotionsUnavailable(f"cannot read the manifest {manifest}: {exc}") from None
    kinds = source_kinds(listed)
    stimuli = study.stimuli.filter(role="judged").order_by("pk")
    shown = {}
    for source, motion_hash in stimuli.values_list("source", "motion_hash"):
        shown.setdefault(source, []).append(motion_hash)
    generated = {s: kinds[s] for s in shown if kinds.get(s) in ("method", "file")}
    unknown = sorted(s for s in shown if s not in kinds)
    if unknown:
        raise MotionsUnavailable(f"sources {', '.join(unknown)} of study {study.slug!r} are not "
                                 f"in its manifest {manifest}; {rebuild}")
    if not generated:
        raise MotionsUnavailable(
            f"study {study.slug!r} has no method sources (its sources: "
            f"{', '.join(sorted(shown)) or 'none'}, all real clips): correlating human scores "
            f"with metrics compares methods; build a study whose sources are methods "
            f"(sources: [real, a2m, cond_gru, ...])")
    folders = [Path(cache)] if cache else list(dict.fromkeys([manifest.parent, default_cache]))
    out = {}
    for source in sorted(generated):
        wanted = shown[source]
        found = {}
        pattern = re.compile(rf"^{re.escape(source)}-[0-9a-f]{{16}}\.npz$")
        for folder in folders:
            for path in sorted((folder / "motions").glob(f"{source}-*.npz")):
                if not pattern.match(path.name):
                    continue
                try:
                    motions = npz.load(path)
                except (OSError, ValueError) as exc:
                    raise MotionsUnavailable(f"cannot read {path} (motions of source "
                                             f"{source!r}): {exc}; {rebuild}") from None
                for motion in motions:
                    found.setdefault(motion.content_hash(), motion)
        missing = [h for h in wanted if h not in found]
        if missing:
            where = ", ".join(str(f / "motions") for f in folders)
            raise MotionsUnavailable(
                f"source {source!r}: {len(missing)} of the {len(wanted)} motions study "
                f"{study.slug!r} showed are not in the build cache ({where}); {rebuild}")
        out[source] = [found[h] for h in wanted]
    return StudyMotions(out, generated, sorted(s for s in shown if kinds[s] == "real"),
                        manifest, folders)


def source_files(found: StudyMotions) -> dict[str, str]:
    """Return per file source of the study the sha256 its build's manifest gives its file."""
    listed = json.loads(found.manifest.read_text())
    return {entry["source"]: entry["file"] for entry in listed.get("clips", [])
            if found.kinds.get(entry.get("source")) == "file" and entry.get("file")}


def source_checkpoints(found: StudyMotions, given: dict | None = None) -> dict:
    """Return per method source of the study ``(method, [checkpoint paths])`` as its
    build's manifest lists its checkpoints (by sha256), or the reason none was found.

    A checkpoint is looked for among ``given`` (source -> path, e.g. ``--source
    a2m=ckpt.pt``: it must have the manifest's sha256) and then in the build cache's
    ``checkpoints/`` folders (where builds train them); a checkpoint the config gave by
    path is found only when given, as the manifest keeps no paths.
    """
    from studyapp.stimuli.clips import file_hash

    given = dict(given or {})
    listed = json.loads(found.manifest.read_text())
    in_cache = None
    out = {}
    for entry in listed.get("sources", []):
        source = entry.get("source")
        if found.kinds.get(source) != "method":
            continue
        wanted = [c.get("checkpoint") for c in entry.get("checkpoints", []) if c.get("checkpoint")]
        if not wanted:
            out[source] = f"the manifest lists no checkpoint of {source!r}"
            continue
        paths = {}
        if source in given:
            path = Path(given[source])
            if not path.is_file():
                raise MotionsUnavailable(f"--source {source}={path}: no such file")
            sha = file_hash(path)
            if sha not in wanted:
                raise MotionsUnavailable(
                    f"--source {source}={path} is not the checkpoint the build of study "
                    f"{found.manifest.parent.name!r} used (its sha256 {sha[:12]} is not "
                    f"{', '.join(w[:12] for w in wanted)})")
            paths[sha] = path
        if len(paths) < len(wanted):
            if in_cache is None:
                in_cache = {}
                for folder in found.cache:
                    for path in sorted((folder / "checkpoints").glob("*/*.pt")):
                        in_cache.setdefault(file_hash(path), path)
            paths.update({sha: in_cache[sha] for sha in wanted if sha in in_cache and sha not in paths})
        missing = [sha for sha in wanted if sha not in paths]
        if missing:
            out[source] = (f"checkpoint(s) {', '.join(sha[:12] for sha in missing)} of {source!r} "
                           f"are neither given (--source {source}=PATH) nor in the build cache "
                           f"({', '.join(str(f / 'checkpoints') for f in found.cache)})")
            continue
        out[source] = (entry.get("method"), [paths[sha] for sha in wanted])
    return out
