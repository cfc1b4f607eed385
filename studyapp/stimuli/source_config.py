"""The training and sources part of a study config: ``train:``, ``sources:`` and ``metrics:``.

:func:`parse_train` reads the defaults of method sources (``iters``, ``preset``,
``schedule``, ``seeds``), :func:`parse_sources` the sources themselves (``real``, a
method, a motions file), checked against the methods, their presets and training
schedules (a budget ending inside a pretraining stage is refused here, before anything
is built), and :func:`parse_metrics` what the build measures per method checkpoint.
Every error names the field, the value and the fix.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from motion.formats import list_formats


class ConfigError(ValueError):
    """A config field has a wrong value; the message names the field, the value and the fix."""


@dataclass
class Source:
    """One source of clips: ``real`` data, a ``method`` checkpoint, or a motions ``file``."""

    name: str
    kind: str  # "real", "method" or "file"
    method: str | None = None
    checkpoint: str | None = None  # None: trained into the build folder with ``train``
    file: str | None = None
    format: str | None = None
    options: dict = field(default_factory=dict)
    seed: int = 0  # sampling seed, and the training seed unless ``seeds`` are given
    iters: int = 1000
    preset: str = "paper"
    schedule: str = "full"  # generation.methods.schedule.SCHEDULES
    seeds: list[int] | None = None  # training seeds: one checkpoint each, clips in turn
    changes: dict | None = None  # config fields changed from the preset (``config:``)
    # A file's motions to use, by the sample and repetition numbers its format records
    # (MDM's results.npy: motion i is sample i % num_samples of repetition i // num_samples).
    samples: list[int] | None = None
    repetitions: list[int] | None = None

    def training_seeds(self) -> list[int]:
        """Return the seeds this method source trains a checkpoint with (one unless ``seeds``)."""
        return list(self.seeds) if self.seeds else [self.seed]

    def section(self) -> dict:
        """Return the fields that decide this source's motions (its cache key, with hashes).

        Fields added since caches were keyed count only when they differ from their
        default, so older caches stay valid.
        """
        out = {k: v for k, v in vars(self).items() if k not in ("checkpoint", "file")}
        if out["schedule"] == "full":
            del out["schedule"]
        for name in ("seeds", "samples", "repetitions", "changes"):
            if out[name] is None:
                del out[name]
        return out


@dataclass
class MetricsConfig:
    """What a build measures per method checkpoint (``metrics:``; ``metrics: false`` for none).

    ``classifier``: a ``train_classifier`` checkpoint for FID, accuracy, diversity and
    multimodality; without it ``train_classifier: true`` trains one on the build's
    training subjects into the cache, else those four are not measured. ``n`` motions
    per action, ``repeats``, ``mmd_protocol`` as ``evaluate``'s.
    """

    enabled: bool = True
    classifier: str | None = None
    train_classifier: bool = False
    classifier_iters: int = 2000
    classifier_preset: str = "augmented"
    n: int = 50
    repeats: int = 5
    mmd_protocol: str = "heldout"


def source_mapping(name: str) -> dict:
    return {"real": True} if name == "real" else {"method": name}


TRAIN_FIELDS = ("iters", "preset", "schedule", "seeds")


def parse_train(train) -> dict:
    """Return the checked ``train:`` defaults of method sources: iters, preset, schedule, seeds."""
    from generation.methods.schedule import SCHEDULES

    if not isinstance(train, dict):
        raise ConfigError(f"train: {train!r} must be a mapping like {{iters: 1000, preset: demo, "
                          f"schedule: benchmark}}")
    unknown = sorted(set(train) - set(TRAIN_FIELDS))
    if unknown:
        raise ConfigError(f"train.{unknown[0]}: not a field of train; its fields are "
                          f"{', '.join(TRAIN_FIELDS)}")
    schedule = _text(train, "schedule", "full", where="train.schedule")
    if schedule not in SCHEDULES:
        raise ConfigError(f"train.schedule: {schedule!r} is not a schedule; choose one of "
                          + "; ".join(f"{k} ({v})" for k, v in SCHEDULES.items()))
    return {"iters": _int(train, "iters", 1000, minimum=0, where="train.iters"),
            "preset": _text(train, "preset", "paper", where="train.preset"),
            "schedule": schedule, "seeds": _seeds(train.get("seeds"), "train.seeds")}


def _seeds(value, where: str) -> list[int] | None:
    """Return a checked list of distinct training seeds, or None."""
    if value is None:
        return None
    if isinstance(value, int) and not isinstance(value, bool):
        value = [value]
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in value)):
        raise ConfigError(f"{where}: {value!r} must be a list of whole numbers of at least 0, "
                          f"e.g. [0, 1, 2]")
    if len(set(value)) != len(value):
        raise ConfigError(f"{where}: {value!r} names a seed twice; give each training seed once")
    return list(value)


def parse_metrics(raw) -> MetricsConfig:
    """Return the checked ``metrics:`` section (``false``: measure nothing)."""
    from motion_metrics.protocol import MMD_PROTOCOLS

    if raw is False:
        return MetricsConfig(enabled=False)
    if raw is None or raw is True:
        raw = {}
    if not isinstance(raw, dict):
        raise ConfigError(f"metrics: {raw!r} must be a mapping like {{train_classifier: true}}, "
                          f"or false to measure nothing")
    known = [f for f in MetricsConfig.__dataclass_fields__]
    unknown = sorted(set(raw) - set(known))
    if unknown:
        raise ConfigError(f"metrics.{unknown[0]}: not a field of metrics; its fields are "
                          f"{', '.join(known)}")
    out = MetricsConfig()
    for name in ("enabled", "train_classifier"):
        if name in raw:
            if not isinstance(raw[name], bool):
                raise ConfigError(f"metrics.{name}: {raw[name]!r} must be true or false")
            setattr(out, name, raw[name])
    if raw.get("classifier") is not None:
        out.classifier = _text(raw, "classifier", where="metrics.classifier")
    out.classifier_preset = _text(raw, "classifier_preset", out.classifier_preset,
                                  where="metrics.classifier_preset")
    from motion_metrics.recognition import ClassifierConfig

    if out.classifier_preset not in ClassifierConfig.PRESETS:
        raise ConfigError(f"metrics.classifier_preset: {out.classifier_preset!r} is not a classifier "
                          f"preset; choose one of {', '.join(sorted(ClassifierConfig.PRESETS))}")
    for name, least in (("classifier_iters", 1), ("n", 2), ("repeats", 1)):
        setattr(out, name, _int(raw, name, getattr(out, name), minimum=least, where=f"metrics.{name}"))
    out.mmd_protocol = _text(raw, "mmd_protocol", out.mmd_protocol, where="metrics.mmd_protocol")
    if out.mmd_protocol not in MMD_PROTOCOLS:
        raise ConfigError(f"metrics.mmd_protocol: {out.mmd_protocol!r} is not an MMD protocol; "
                          f"choose one of {', '.join(sorted(MMD_PROTOCOLS))}")
    return out


def parse_sources(raw, seed, train) -> list[Source]:
    if not isinstance(raw, list) or not raw:
        raise ConfigError(f"sources: {raw!r} must be a non-empty list, e.g. [real, cond_gru]")
    sources = []
    for i, entry in enumerate(raw):
        where = f"sources.{i}"
        if isinstance(entry, str):
            entry = source_mapping(entry)
        if not isinstance(entry, dict):
            raise ConfigError(f"{where}: {entry!r} must be 'real', a method name or a mapping")
        kinds = [k for k in ("real", "method", "file") if entry.get(k)]
        if len(kinds) != 1:
            raise ConfigError(f"{where}: {entry!r} needs exactly one of real: true, method: NAME, "
                              f"file: PATH")
        kind = kinds[0]
        allowed = {"name", "seed", kind} | {
            "real": set(), "method": {"checkpoint", "iters", "preset", "schedule", "seeds", "config"},
            "file": {"format", "options", "samples", "repetitions"},
        }[kind]
        extra = sorted(set(entry) - allowed)
        if extra:
            raise ConfigError(f"{where}.{extra[0]}: not a field of a {kind} source; "
                              f"its fields are {', '.join(sorted(allowed))}")
        source = Source(
            name=str(entry.get("name") or ("real" if kind == "real" else entry.get("method")
                                           or Path(str(entry["file"])).stem)),
            kind=kind,
            seed=_int(entry, "seed", seed, minimum=0, where=f"{where}.seed"),
        )
        if kind == "method":
            source.method = _text(entry, "method", where=f"{where}.method")
            source.checkpoint = entry.get("checkpoint")
            source.iters = _int(entry, "iters", train["iters"], minimum=1, where=f"{where}.iters")
            source.preset = _text(entry, "preset", train["preset"], where=f"{where}.preset")
            source.schedule = _text(entry, "schedule", train["schedule"], where=f"{where}.schedule")
            source.seeds = (_seeds(entry["seeds"], f"{where}.seeds") if "seeds" in entry
                            else train["seeds"])
            if source.checkpoint is not None and "seeds" in entry:
                raise ConfigError(f"{where}.seeds: a source with a checkpoint has that checkpoint's "
                                  f"training seed; drop seeds, or drop checkpoint to train one per "
                                  f"seed")
            if source.checkpoint is not None:
                source.seeds = None
            if entry.get("config") is not None:
                if not isinstance(entry["config"], dict) or not entry["config"]:
                    raise ConfigError(f"{where}.config: {entry['config']!r} must be a mapping of "
                                      f"the method's config fields, e.g. {{init: he}}")
                if source.checkpoint is not None:
                    raise ConfigError(f"{where}.config: a source with a checkpoint has that "
                                      f"checkpoint's config; drop config, or drop checkpoint to "
                                      f"train one with it")
                source.changes = dict(entry["config"])
            _check_method(source, where)
        elif kind == "file":
            source.file = str(entry["file"])
            source.format = entry.get("format") or Path(source.file).suffix.lstrip(".")
            if source.format not in list_formats():
                raise ConfigError(f"{where}.format: {source.format!r} is not a motion format; "
                                  f"choose one of {', '.join(list_formats())}")
            source.options = dict(entry.get("options") or {})
            for name in ("samples", "repetitions"):
                if entry.get(name) is not None:
                    setattr(source, name, _numbers(entry[name], f"{where}.{name}"))
        if source.name in [s.name for s in sources]:
            raise ConfigError(f"{where}.name: {source.name!r} is used twice; give each source "
                              f"its own name")
        sources.append(source)
    return sources


def _check_method(source: Source, where: str) -> None:
    from generation.methods import get_method, list_methods

    try:
        cls = get_method(source.method)
    except KeyError:
        raise ConfigError(f"{where}.method: {source.method!r} is not a method; choose one of "
                          f"{', '.join(list_methods())}") from None
    if source.checkpoint is not None:
        return
    if source.preset not in cls.Config.PRESETS:
        raise ConfigError(f"{where}.preset (or train.preset): {source.preset!r} is not a preset "
                          f"of {source.method}; choose one of {', '.join(sorted(cls.Config.PRESETS))}")
    from generation.methods.schedule import SCHEDULES, ScheduleError, check_changes, recipe_for

    if source.schedule not in SCHEDULES:
        raise ConfigError(f"{where}.schedule (or train.schedule): {source.schedule!r} is not a "
                          f"schedule; choose one of {', '.join(SCHEDULES)}")
    if source.changes:
        try:
            source.changes = check_changes(source.method, source.preset, source.changes)
        except ScheduleError as exc:
            raise ConfigError(f"{where}.config: {exc}") from None
    try:
        recipe_for(source.method, source.preset, source.iters, source.schedule, source.changes)
    except ScheduleError as exc:
        raise ConfigError(f"{where}.iters (or train.iters): {exc}") from None


def _numbers(value, where: str) -> list[int]:
    """Return a selection of sample or repetition numbers: a number, a list of numbers or a
    range ``"0-4"`` (both ends included)."""
    if isinstance(value, str) and "-" in value:
        low, _, high = value.partition("-")
        if low.strip().isdigit() and high.strip().isdigit() and int(low) <= int(high):
            return list(range(int(low), int(high) + 1))
    if isinstance(value, int) and not isinstance(value, bool):
        value = [value]
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in value)):
        raise ConfigError(f"{where}: {value!r} must be a number, a list of numbers from 0 or a "
                          f"range such as \"0-4\"")
    return sorted(set(value))


def _text(raw: dict, name: str, default=None, where=None) -> str:
    value = raw.get(name, default)
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"{where or name}: {value!r} must be a non-empty text")
    return value


def _int(raw: dict, name: str, default, minimum=None, where=None):
    value = raw.get(name, default)
    if value is None and default is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or (minimum is not None and value < minimum):
        raise ConfigError(f"{where or name}: {value!r} must be a whole number of at least {minimum}")
    return value


