"""Read and check a stimulus-set config (YAML): what ``manage.py build_stimuli`` builds.

A config names the dataset, the clips, the sources, the render settings and the study
(see ``studies/*.yaml`` for documented examples). :func:`load_config` applies
``--set`` overrides, then checks every field against the registries it names (study
types and their options, render styles, motion formats, methods and their presets,
crowd platforms); each error names the field, the value and the fix.

Overrides are ``path=value``: ``path`` is dotted (``train.iters``, ``study.type``,
``sources.2.seed`` for the third source) and ``value`` is read as YAML
(``3``, ``tiny``, ``[walk, run]``, ``null``).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from motion.datasets.humanml3d import normalise as normalise_prompt  # as captions match
from rendering import get_style, list_styles
from studyapp.participation import duration
from studyapp.crowd.platform import make_platform, outcomes_of
from studyapp.survey.models import Study
from studyapp.survey.study_types import get_study_type, list_study_types
from studyapp.participation import adaptive, arena
from studyapp.survey.study_types.base import COMMON_OPTIONS, check_criteria
# The training and sources part (re-exported: callers import ConfigError and Source from here).
from studyapp.stimuli.source_config import (  # noqa: F401
    ConfigError,
    MetricsConfig,
    Source,
    _int,
    _text,
    parse_metrics,
    parse_sources,
    parse_train,
    source_mapping,
)

TOP = ("slug", "title", "seed", "dataset", "data_root", "subjects", "actions", "prompts",
       "prompts_from", "frames", "fps", "clips_per_source", "train", "sources", "metrics",
       "render", "study")
MAX_EXTENDS = 5
PLAYERS = ("video", "webgl")
MAX_PROMPT = 500  # characters of one prompt
# Trials group clips by their action field; a prompt longer than it holds is cut and
# made unique with a hash of the whole prompt.
ACTION_LENGTH = 100


@dataclass
class StudyConfig:
    slug: str
    title: str
    seed: int
    dataset: str
    data_root: str | None
    subjects: list[str] | None
    actions: list[str] | None
    frames: int | None  # None: the dataset's clip length (or, with frames_auto, see below)
    fps: float | None
    clips_per_source: int
    sources: list[Source]
    style: str
    size: int
    player: str  # "video" (the mp4) or "webgl" (the in-browser player, the mp4 as fallback)
    study_type: str
    study_options: dict  # Study fields every type has (clips_per_trial, crowd, ...)
    type_options: dict  # the study type's own options (Study.options)
    folder: Path  # relative paths in the config are relative to this
    # Text prompts instead of actions (``prompts`` or ``prompts_from``): each trial shows
    # one prompt and every source's clips of it.
    prompts: list[str] | None = None
    # What the crowd platform's rules advise against (the build goes on; the command
    # prints them), e.g. too few attention checks for Prolific.
    warnings: list[str] = field(default_factory=list)
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    # ``frames: auto``: the longest length every file source's motions have (Build.clip_frames)
    frames_auto: bool = False
    # ``prompts_from: sources``: the prompts every file source has, found when a build
    # reads the files (Build.shared_prompts sets ``prompts``)
    prompts_shared: bool = False

    def path(self, value: str) -> Path:
        return (self.folder / value).resolve()

    def kind(self):
        """Return the study type this config builds (its roles, defaults and options)."""
        return get_study_type(self.study_type)


def load_config(path, overrides=()) -> StudyConfig:
    """Read the YAML config at ``path``, apply ``path=value`` overrides and check it.

    A config may start from another: ``extends: FILE`` (relative to the config) reads
    FILE first, then this config's fields over it (mappings merge field by field; lists
    and values replace). Relative paths in either are relative to the config loaded.
    """
    path = Path(path)
    raw = _read_mapping(path)
    for override in overrides:
        apply_override(raw, override)
    return parse(raw, path.resolve().parent)


def resolved_mapping(path, overrides=()) -> dict:
    """Return the fields of the config at ``path`` as built: ``extends`` merged and the
    ``path=value`` overrides applied (what ``build_stimuli`` keeps beside the manifest)."""
    raw = _read_mapping(Path(path))
    for override in overrides:
        apply_override(raw, override)
    return raw


def _read_mapping(path: Path, depth: int = 0) -> dict:
    try:
        raw = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read config {path}: {exc.strerror}; check the path") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"config {path} is not valid YAML: {exc}") from None
    if not isinstance(raw, dict):
        raise ConfigError(f"config {path} must be a mapping of fields (slug, dataset, sources, ...)")
    base = raw.pop("extends", None)
    if base is None:
        return raw
    if not isinstance(base, str) or depth >= MAX_EXTENDS:
        raise ConfigError(f"{path}: extends: {base!r} must name one config file (at most "
                          f"{MAX_EXTENDS} deep)")
    return _merge(_read_mapping(path.parent / base, depth + 1), raw)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def apply_override(raw: dict, override: str) -> None:
    """Set ``raw[a][b]...`` from ``"a.b=value"`` (value read as YAML) in place."""
    key, sep, text = override.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {override!r}: write FIELD=VALUE, e.g. --set train.iters=3")
    parts = key.strip().split(".")
    value = yaml.safe_load(text) if text.strip() else None
    node = raw
    for i, part in enumerate(parts[:-1]):
        node = _child(node, part, ".".join(parts[: i + 1]), create=True)
    last = parts[-1]
    if isinstance(node, list):
        node[_index(node, last, key)] = value
    else:
        node[last] = value


def _child(node, part, where, create):
    if isinstance(node, list):
        index = _index(node, part, where)
        if isinstance(node[index], str):  # a source given by name becomes a mapping
            node[index] = source_mapping(node[index])
        return node[index]
    if not isinstance(node, dict):
        raise ConfigError(f"--set {where}: {where.rsplit('.', 1)[0]} holds no fields")
    if node.get(part) is None and create:
        node[part] = {}
    return node[part]


def _index(node: list, part: str, where: str) -> int:
    if not part.isdigit() or int(part) >= len(node):
        raise ConfigError(f"--set {where}: {part!r} is not an index of the list "
                          f"(0 to {len(node) - 1})")
    return int(part)


def parse(raw: dict, folder: Path) -> StudyConfig:
    """Check a config mapping; raise :class:`ConfigError` naming the first bad field."""
    unknown = sorted(set(raw) - set(TOP))
    if unknown:
        raise ConfigError(f"unknown field {unknown[0]!r}; fields are: {', '.join(TOP)}")
    slug = _text(raw, "slug")
    if not slug.replace("-", "").replace("_", "").isalnum():
        raise ConfigError(f"slug: {slug!r} is not a slug; use letters, digits, - and _")
    seed = _int(raw, "seed", 0, minimum=0)
    train = parse_train(raw.get("train") or {})
    render = raw.get("render") or {}
    style = _text(render, "style", "stick", where="render.style")
    if style not in list_styles():
        raise ConfigError(f"render.style: {style!r} is not a style; choose one of "
                          f"{', '.join(list_styles())}")
    player = _text(render, "player", "video", where="render.player")
    if player not in PLAYERS:
        raise ConfigError(f"render.player: {player!r} is not a player; choose one of "
                          f"{', '.join(PLAYERS)} (video plays the mp4; webgl draws the motion "
                          f"in the page, with the mp4 where WebGL 2 is missing)")
    if player == "webgl" and not get_style(style).player_figure:
        drawn = [name for name in list_styles() if get_style(name).player_figure]
        raise ConfigError(f"render.player: webgl cannot draw {style!r} clips; use a style it "
                          f"draws ({', '.join(drawn)}), or player video for {style} clips")
    study_type, options, type_options, warnings = _study(raw.get("study") or {},
                                                         *_session_size(raw))
    sources = parse_sources(raw.get("sources"), seed, train)
    fps = raw.get("fps")
    if fps is not None and (isinstance(fps, bool) or not isinstance(fps, (int, float)) or fps <= 0):
        raise ConfigError(f"fps: {fps!r} must be a positive number, or null for the dataset's")
    shared = raw.get("prompts_from") == SHARED_PROMPTS
    if shared and raw.get("prompts") is not None:
        raise ConfigError("prompts and prompts_from: give one of them (a list of prompts, or "
                          "prompts_from: sources for the prompts every file source shares)")
    if shared and raw.get("actions") is not None:
        raise ConfigError("actions and prompts_from: a study's trials show either actions or "
                          "text prompts; drop actions (or prompts_from)")
    prompts = None if shared else _prompts(raw, folder)
    if prompts is not None or shared:
        _check_prompt_study(raw, sources, study_type, options, type_options)
    return StudyConfig(
        slug=slug,
        title=_text(raw, "title"),
        seed=seed,
        dataset=_text(raw, "dataset"),
        data_root=raw.get("data_root"),
        subjects=_names(raw, "subjects"),
        actions=_names(raw, "actions"),
        frames=None if raw.get("frames") == "auto" else _int(raw, "frames", None, minimum=2),
        frames_auto=raw.get("frames") == "auto",
        prompts_shared=shared,
        fps=fps,
        clips_per_source=_int(raw, "clips_per_source", 1, minimum=1),
        sources=sources,
        style=style,
        size=_int(render, "size", 480, minimum=16, where="render.size"),
        player=player,
        study_type=study_type,
        study_options=options,
        type_options=type_options,
        folder=folder,
        prompts=prompts,
        warnings=warnings,
        metrics=parse_metrics(raw.get("metrics", {})),
    )


def _session_size(raw: dict) -> tuple[int | None, float | None]:
    """Return the conditions a config names (actions or prompts; None: the data decides)
    and its clips' seconds (frames / fps; None when the dataset decides either)."""
    named = [raw.get(key) for key in ("actions", "prompts")]
    conditions = next((len(v) for v in named if isinstance(v, list) and v), None)
    frames, fps = raw.get("frames"), raw.get("fps")
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0
                  for v in (frames, fps))
    return conditions, (frames / fps if numbers else None)


def _study(raw, conditions=None, clip_seconds=None) -> tuple[str, dict, dict, list[str]]:
    """Return the study type, its common fields and its own options, checked, and the
    crowd platform's warnings.

    The study's length is estimated from the config (:func:`.duration.config_minutes`:
    ``conditions`` trials, clips of ``clip_seconds``; assumed where the data decides). A
    Prolific study estimated over 5 minutes whose config names neither
    ``catch_trials`` nor ``instructed_checks`` gets two instructed checks (Prolific's
    policy); every outcome it can end with must have its code (:mod:`.crowd`).
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"study: {raw!r} must be a mapping like {{type: ranking}}")
    raw = dict(raw)
    study_type = raw.pop("type", None)
    if study_type not in list_study_types():
        raise ConfigError(f"study.type: {study_type!r} is not a study type; choose one of "
                          f"{', '.join(list_study_types())}")
    kind = get_study_type(study_type)
    options, own = {}, {}
    for name, value in raw.items():
        if name in kind.options:
            own[name] = value
            continue
        expected = COMMON_OPTIONS.get(name)
        if expected is None:
            known = ", ".join(["type", *COMMON_OPTIONS, *kind.options])
            raise ConfigError(f"study.{name}: not an option of {study_type} studies; options "
                              f"are {known}")
        if value is not None and (not isinstance(value, expected)
                                  or (expected is int and isinstance(value, bool))):
            raise ConfigError(f"study.{name}: {value!r} must be {expected.__name__}")
        if expected is int and value is not None and value < 0:
            raise ConfigError(f"study.{name}: {value!r} must be 0 or more")
        options[name] = value
    try:
        own = kind.check_options(own)
        platform = make_platform(options.get("crowd"))
    except ValueError as exc:
        raise ConfigError(f"study.{exc}") from None
    problem = check_criteria(options.get("criteria"))
    if problem:
        raise ConfigError(f"study.{problem}")
    problem = (adaptive.check(options.get("design") or "balanced", options.get("adaptive"), study_type)
               or adaptive.check_stop(options.get("stop_when"), study_type))
    if problem:
        raise ConfigError(f"study.{problem}")
    if options.get("arena") is not None:  # arena: {} is an arena of the default settings
        options["arena"], problem = arena.check(options["arena"] or True,
                                                options.get("design") or "balanced",
                                                adaptive.model(study_type) == "pairs",
                                                options.get("stop_when"))
        if problem:
            raise ConfigError(f"study.{problem}")
    given = "catch_trials" in options or "instructed_checks" in options
    minutes = _config_minutes(study_type, options, own, conditions, clip_seconds)
    if not given and platform.default_checks(minutes):
        options["instructed_checks"] = platform.default_checks(minutes)
        minutes = _config_minutes(study_type, options, own, conditions, clip_seconds)
    checks = (options.get("catch_trials") or 0) + (options.get("instructed_checks") or 0)
    try:
        platform.check_codes(outcomes_of(checks, bool(platform.screening)), checks)
    except ValueError as exc:
        default = "" if given or not checks else (
            f" (study.instructed_checks defaults to {checks} for this platform in a study "
            f"estimated at {minutes} minutes)")
        raise ConfigError(f"study.{exc}{default}") from None
    max_failed = options.get("max_failed_catch")
    if max_failed is None:
        max_failed = Study._meta.get_field("max_failed_catch").default
    return study_type, options, own, platform.warnings(minutes, checks, max_failed)


def _config_minutes(study_type, options, own, conditions, clip_seconds) -> int:
    """Return the minutes of a study of these settings, estimated before its build."""
    fields = {name: value for name, value in options.items()
              if name in duration.SETTINGS and value is not None}
    study = Study(study_type=study_type, options=own, **fields)
    if not options.get("clips_per_trial"):
        study.clips_per_trial = get_study_type(study_type).default_clips_per_trial
    return duration.config_minutes(study, conditions, clip_seconds)


def prompt_key(prompt: str) -> str:
    """Return the ``action`` of a prompt's clips: the prompt itself, or, when it is longer
    than the field holds, its start and a hash of the whole prompt."""
    prompt = " ".join(prompt.split())
    if len(prompt) <= ACTION_LENGTH:
        return prompt
    tag = hashlib.sha256(prompt.encode()).hexdigest()[:8]
    return f"{prompt[:ACTION_LENGTH - 10].rstrip()}~{tag}"


def _prompts(raw: dict, folder: Path) -> list[str] | None:
    """Return the config's prompts (``prompts`` or ``prompts_from``), checked, or None."""
    given, from_file = raw.get("prompts"), raw.get("prompts_from")
    if given is None and from_file is None:
        return None
    if given is not None and from_file is not None:
        raise ConfigError("prompts and prompts_from: give one of them (a list of prompts, or a "
                          "file with one prompt per line); set the other to null, e.g. over a "
                          "config this one extends")
    key = "prompts" if given is not None else "prompts_from"
    if raw.get("actions") is not None:
        raise ConfigError(f"actions and {key}: a study's trials show either actions or text "
                          f"prompts; drop actions (or {key})")
    if given is not None:
        if isinstance(given, str):
            given = [given]
        if not isinstance(given, list) or not given:
            raise ConfigError(f"prompts: {given!r} must be a non-empty list of texts, e.g. "
                              f"[\"a person walks forward\", \"a person jumps\"]")
        prompts, where = given, "prompts"
    else:
        prompts, where = _read_prompt_file(from_file, folder), f"prompts_from ({from_file})"
    seen = {}
    out = []
    for i, prompt in enumerate(prompts):
        if not isinstance(prompt, str) or not prompt.strip():
            raise ConfigError(f"{where}: prompt {i + 1} ({prompt!r}) must be a non-empty text")
        prompt = " ".join(prompt.split())
        if len(prompt) > MAX_PROMPT:
            raise ConfigError(f"{where}: prompt {i + 1} has {len(prompt)} characters; a prompt "
                              f"has at most {MAX_PROMPT} (shorten it)")
        norm = normalise_prompt(prompt)
        if norm in seen:
            if given is None:
                continue  # a file of generated prompts repeats them (one line per motion)
            raise ConfigError(f"prompts: {prompt!r} (prompt {i + 1}) is the same prompt as "
                              f"{seen[norm]!r}; give each prompt once")
        seen[norm] = prompt
        out.append(prompt)
    return out


def _read_prompt_file(value, folder: Path) -> list:
    """Return the prompts of ``prompts_from``: lines of a text file (``caption#...`` keeps the
    caption, ``#`` comment lines and blank lines are skipped) or an interchange .npz's texts."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"prompts_from: {value!r} must be the path of a text file (one prompt "
                          f"per line) or of an interchange .npz with texts")
    path = (folder / value).resolve()
    if not path.is_file():
        raise ConfigError(f"prompts_from: {value!r} is not there (looked in {path}); fix the path")
    if path.suffix == ".npz":
        from motion.formats import npz
        from motion.formats.base import FormatError

        try:
            texts = [m.text or "" for m in npz.load(path)]
        except (FormatError, ValueError, OSError) as exc:
            raise ConfigError(f"prompts_from: {value!r} cannot be read as an interchange .npz: "
                              f"{exc}") from None
        texts = [t for t in texts if t.strip()]
        if not texts:
            raise ConfigError(f"prompts_from: {value!r} has no texts; import motions that carry "
                              f"prompts (import_motions ... --texts FILE), or give a text file")
        return texts
    if path.suffix.lower() == ".csv":  # a text (or prompt, caption) column, as --texts reads
        from motion.formats.base import FormatError, read_prompts

        try:
            found = read_prompts(path)
        except (FormatError, UnicodeDecodeError) as exc:
            raise ConfigError(f"prompts_from: {value!r}: {exc}") from None
        texts = list(found.values()) if isinstance(found, dict) else found
        return [t for t in texts if t.strip()] or _no_prompt(value)
    if path.suffix in (".npy", ".pt", ".pkl", ".bvh"):
        raise ConfigError(f"prompts_from: {value!r} is not a text file; give one prompt per line, "
                          f"or an interchange .npz (import_motions {value} --format auto --out "
                          f"F.npz) to use its texts")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"prompts_from: {value!r} cannot be read as UTF-8 text: {exc}") from None
    lines = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        lines.append(line.split("#", 1)[0])
    return lines or _no_prompt(value)


def _no_prompt(value):
    raise ConfigError(f"prompts_from: {value!r} holds no prompt; write one prompt per line")


SHARED_PROMPTS = "sources"  # prompts_from: sources


# Roles a prompts study can make: catch clips are broken versions of judged clips; the
# others need real clips of the condition beyond the judged ones.
PROMPT_ROLES = ("catch",)


def _check_prompt_study(raw, sources, study_type, options, type_options) -> None:
    key = "prompts" if raw.get("prompts") is not None else "prompts_from"
    for i, source in enumerate(sources):
        if source.kind == "method":
            raise ConfigError(f"sources.{i}: method {source.method!r} is action-conditioned and "
                              f"cannot follow {key}; give text-to-motion outputs as a file "
                              f"source (file: results.npy, format: mdm), or use actions")
    roles = get_study_type(study_type).stimulus_roles({**options, **type_options})
    for role in roles:
        if role in PROMPT_ROLES:
            continue
        if role == "practice":
            raise ConfigError(f"study.practice: a study of {key} has no clips to spare for a "
                              f"practice trial; set study.practice: false")
        fit = [k for k in list_study_types() if all(
            r in PROMPT_ROLES for r in get_study_type(k).stimulus_roles({"practice": False}))]
        raise ConfigError(f"study.type: {study_type} studies need {role} clips per action, which "
                          f"a study of {key} does not make; use {', '.join(fit)}, or actions")


def _names(raw: dict, name: str) -> list[str] | None:
    value = raw.get(name)
    if value is None or value == "all":
        return None
    if isinstance(value, str):
        value = [v.strip() for v in value.split(",") if v.strip()]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{name}: {value!r} must be a list of names, or null for all")
    return value
