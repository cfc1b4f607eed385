"""A study's bundle: everything a reviewer needs to check its numbers and rebuild its clips.

``bundle --study SLUG --out F.zip`` writes one zip:

- ``config.yaml``: the study's config as built (``extends`` merged, overrides applied),
  from the build folder (``build_stimuli`` keeps it there) or ``--config``;
- ``manifest.json``: the build's manifest (every clip's source, seed, motion and video
  hash; each method's checkpoints and metrics);
- ``motions/<source>.npz``: the motions the build sampled of each source (the
  interchange format), and ``bvh/<source>/<motion hash>.bvh`` of every stimulus motion
  among them (:func:`motion.formats.bvh.save`);
- ``rebuild.yaml``: the config with every method and file source read from
  ``motions/<source>.npz``, so ``build_stimuli rebuild.yaml`` makes the same clips again
  without training (real sources still come from the dataset);
- ``stimuli.csv``: every stimulus (source, role, action, prompt, motion and video hash,
  its files in the bundle; catch, anchor and practice clips the build derives from the
  source motions have no file of their own);
- ``responses.csv`` (the export), ``analysis/`` (``analyze --responses responses.csv``
  with the study's exclusion settings, the very command in ``bundle.json``), and
  ``bundle.json``: the study, the command that re-runs the analysis, package versions and
  the code's commit.
"""

from __future__ import annotations

import csv
import io
import json
import platform
import subprocess
import tempfile
import zipfile
from importlib import metadata
from pathlib import Path

import yaml

PACKAGES = ("numpy", "scipy", "pandas", "statsmodels", "torch", "smplx", "Django",
            "matplotlib", "PyYAML")
BVH_UNITS = "cm"


class BundleError(ValueError):
    """A study cannot be bundled (no build manifest, no motions); the message says why."""


def versions() -> dict[str, str]:
    """Return the versions of Python and the packages the numbers depend on."""
    found = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


def commit(root: Path) -> str:
    """Return the code's git commit (with ``+changes`` when the tree differs), or why not."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=root, capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    return head + ("+changes" if dirty.strip() else "")


def cached_motions(cache: list[Path], shown: dict[str, set]) -> dict[str, list]:
    """Return, per source, the motions of the build cache file that holds the motions the
    study showed of it (``shown``: source -> motion hashes); other builds' files of the
    same source (an older config's) are left out."""
    from motion.formats import npz

    out = {}
    for source, hashes in shown.items():
        for folder in dict.fromkeys(cache):
            for path in sorted((folder / "motions").glob(f"{source}-*.npz")):
                if len(path.stem) != len(source) + 17:  # <source>-<16 hex>
                    continue
                motions = npz.load(path)
                if hashes & {motion.content_hash() for motion in motions}:
                    out.setdefault(source, []).extend(motions)
    return out


def rebuild_config(config: dict, folder: Path, sources: dict[str, str]) -> dict:
    """Return ``config`` with method and file sources read from the bundle's motions.

    ``sources`` maps each source name to its bundle file; ``folder`` is the config's own
    folder, against which a relative ``data_root`` is made absolute.
    """
    raw = json.loads(json.dumps(config))
    raw["slug"] = f"{raw['slug']}-rebuilt"
    if raw.get("data_root") and not Path(raw["data_root"]).is_absolute():
        raw["data_root"] = str((folder / raw["data_root"]).resolve())
    rebuilt = []
    for entry in raw.get("sources", []):
        name = entry if isinstance(entry, str) else entry.get("name") or entry.get("method") \
            or entry.get("file")
        if name in sources:
            seed = entry.get("seed", 0) if isinstance(entry, dict) else 0
            rebuilt.append({"name": name, "file": sources[name], "format": "npz", "seed": seed})
        else:
            rebuilt.append(entry)
    raw["sources"] = rebuilt
    raw.pop("train", None)
    return raw


def write_bundle(study, out: Path, folder: Path, cache: list[Path], config_path=None,
                 code_root: Path | None = None, log=print) -> Path:
    """Write ``study``'s bundle (see the module docstring) to ``out`` and return its path."""
    from django.core.management import call_command

    from analysis.tables import write_responses
    from motion.formats import bvh, npz
    from studyapp.results.export import responses_frame
    from studyapp.results.study_motions import source_kinds

    manifest = folder / "manifest.json"
    if not manifest.is_file():
        raise BundleError(f"study {study.slug!r} has no build manifest at {manifest}; pass "
                          "--manifest DIR/manifest.json (and --cache DIR) for a study built "
                          "with --out DIR, or rebuild it with build_stimuli CONFIG")
    listed = json.loads(manifest.read_text())
    config_path = Path(config_path) if config_path else folder / "config.yaml"
    if not config_path.is_file():
        raise BundleError(f"no config at {config_path}: pass --config CONFIG, the YAML that "
                          f"built study {study.slug!r} (build_stimuli keeps a copy in the "
                          "build folder)")
    from studyapp.stimuli.config import resolved_mapping

    config = resolved_mapping(config_path)
    kinds = source_kinds(listed)
    stimuli = list(study.stimuli.order_by("pk").values(
        "source", "role", "action", "prompt", "motion_hash", "video_hash", "duration"))
    shown: dict[str, set] = {}
    for stimulus in stimuli:
        shown.setdefault(stimulus["source"], set()).add(stimulus["motion_hash"])
    motions = cached_motions(cache, shown)
    missing = sorted({s["source"] for s in stimuli if s["role"] == "judged"} - set(motions))
    if missing:
        raise BundleError(f"the build cache ({', '.join(map(str, cache))}) holds no motions of "
                          f"{', '.join(missing)}; pass --cache DIR (the build's), or rebuild "
                          f"study {study.slug!r} with build_stimuli CONFIG")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    table = responses_frame(study)
    with tempfile.TemporaryDirectory() as scratch, \
            zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        scratch = Path(scratch)
        archive.writestr("config.yaml", yaml.safe_dump(config, sort_keys=False))
        archive.write(manifest, "manifest.json")
        files, by_hash = {}, {}
        for source, found in motions.items():
            name = f"motions/{source}.npz"
            npz.save(scratch / f"{source}.npz", found)
            archive.write(scratch / f"{source}.npz", name)
            files[source] = name
            for motion in found:
                by_hash.setdefault(motion.content_hash(), (source, motion))
        rows = []
        for stimulus in stimuli:
            entry = {**stimulus, "motion_file": "", "bvh_file": ""}
            hit = by_hash.get(stimulus["motion_hash"])
            if hit is not None:
                source, motion = hit
                entry["motion_file"] = files[source]
                target = f"bvh/{source}/{stimulus['motion_hash']}.bvh"
                if target not in archive.namelist():
                    bvh.save(scratch / "clip.bvh", motion, units=BVH_UNITS)
                    archive.write(scratch / "clip.bvh", target)
                entry["bvh_file"] = target
            rows.append(entry)
        archive.writestr("stimuli.csv", _csv(rows))
        rebuild = {name: files[name] for name, kind in kinds.items()
                   if kind in ("method", "file") and name in files}
        archive.writestr("rebuild.yaml", yaml.safe_dump(
            rebuild_config(config, config_path.resolve().parent, rebuild), sort_keys=False))
        responses = write_responses(table, scratch / "responses.csv")
        archive.write(responses, "responses.csv")
        command = ["analyze", "--responses", "responses.csv", "--max-failed-catch",
                   str(study.max_failed_catch), "--out", "analysis"]
        analysed = False
        if not table.empty:
            call_command(command[0], "--responses", str(responses), "--max-failed-catch",
                         str(study.max_failed_catch), "--out", str(scratch / "analysis"),
                         stdout=io.StringIO())
            for path in sorted((scratch / "analysis").rglob("*")):
                if path.is_file():
                    archive.write(path, f"analysis/{path.relative_to(scratch / 'analysis')}")
            analysed = True
        info = {
            "study": {"slug": study.slug, "title": study.title, "type": study.study_type,
                      "stimuli": len(stimuli), "responses": int(len(table))},
            "analysis": {"command": "manage.py " + " ".join(command), "written": analysed,
                         "note": "the blindness audit needs the running site: run "
                                 "audit_blindness there"},
            "rebuild": "manage.py build_stimuli rebuild.yaml --out DIR (its method and file "
                       "sources read motions/<source>.npz; real clips come from the dataset)",
            "clip_hashes": {"motion": sorted({s["motion_hash"] for s in stimuli}),
                            "video": sorted({s["video_hash"] for s in stimuli})},
            "versions": versions(),
            "commit": commit(code_root or Path(__file__).resolve().parents[2]),
        }
        archive.writestr("bundle.json", json.dumps(info, indent=1) + "\n")
    log(f"bundle of study {study.slug}: {len(stimuli)} stimuli, {len(by_hash)} motions of "
        f"{len(motions)} sources, {len(table)} response rows{', analysed' if analysed else ''}"
        f" -> {out}")
    return out


def _csv(rows: list[dict]) -> str:
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]) if rows else ["source"])
    writer.writeheader()
    writer.writerows(rows)
    return text.getvalue()
