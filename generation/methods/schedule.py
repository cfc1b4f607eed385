"""How a method trains for a budget of iterations: its preset, its phases, and the rule for them.

Some methods train in phases: a first phase (pretraining a pose or frame model, or ODMO's
decaying teacher forcing) of a fixed number of iterations in the preset, then the rest.
A budget shorter than the first phase never reaches the second, so every training path
(``manage.py train``, ``compare_methods``, a study build) takes one of two rules
(:data:`SCHEDULES`):

- ``benchmark``: the first phase takes its share (:data:`PHASES`) of the budget where
  that is less than the preset's count, so the second phase always gets the rest; this
  is what ``compare_methods --iters N`` trains, so a checkpoint trained so is the one
  its results measure;
- ``full``: the preset's phases as they are; a budget that ends inside a first stage (a
  pose or frame model trained before the sequence model) is refused, naming it
  (:func:`check_budget`); ODMO's teacher forcing may be cut short (its networks all
  train from the start).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from generation.methods.base import MethodError


@dataclass(frozen=True)
class Phase:
    """A method's first training phase: its config field, its share of a budget, what it does.

    ``stage`` phases train other networks than the rest of the training (a pose or frame
    model before the sequence model): a budget ending inside one leaves the sequence model
    untrained. ODMO's teacher forcing only decays, and every network trains from the start.
    """

    field: str
    share: float
    what: str
    stage: bool = True


PHASES = {
    "skeleton_gan": Phase("pretrain_iters", 0.5, "pretrains its single-pose GAN"),
    "c_skeleton_gan": Phase("pretrain_iters", 0.5, "pretrains its frame decoder"),
    "two_stage_gan": Phase("pose_iterations", 0.5, "trains its pose GAN before the motion generator"),
    "odmo": Phase("teacher_forcing_iters", 0.75, "decays its teacher forcing", stage=False),
    "odmo_conv": Phase("teacher_forcing_iters", 0.75, "decays its teacher forcing", stage=False),
}
SCHEDULES = {
    "benchmark": "a first phase longer than its share of the budget is shortened to that share, "
                 "as compare_methods trains",
    "full": "the preset's phase lengths as they are; a budget ending inside a first stage "
            "(pretraining) is refused",
}


class ScheduleError(MethodError):
    """A budget cannot train a method as asked (it ends inside a first phase, or no such rule)."""


@dataclass(frozen=True)
class Recipe:
    """How a method is built for the budget: a config preset and changes to it."""

    preset: str = "demo"
    changes: dict = field(default_factory=dict)

    def describe(self) -> str:
        changed = ", ".join(f"{key}={value}" for key, value in self.changes.items())
        return f"{self.preset} ({changed})" if changed else self.preset

    def config(self, cls):
        return replace(cls.Config.preset(self.preset), **self.changes)


def check_changes(method: str, preset: str, changes: dict | None) -> dict:
    """Return ``changes`` to ``method``'s ``preset`` config, checked: every name a field of
    its config, each value of the field's type (a whole number where a float is asked is
    taken), the changed config valid. Raise :class:`ScheduleError` naming the field."""
    from dataclasses import fields

    from generation.methods import get_method

    changes = dict(changes or {})
    cls = get_method(method)
    known = {f.name: f for f in fields(cls.Config)}
    base = cls.Config.preset(preset)
    for name, value in changes.items():
        if name not in known:
            raise ScheduleError(f"{method} has no config field {name!r}; its fields are "
                                f"{', '.join(sorted(known))}")
        default = getattr(base, name)
        if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            changes[name] = value = float(value)
        if default is not None and type(value) is not type(default):
            raise ScheduleError(f"{method} config {name}: {value!r} must be a "
                                f"{type(default).__name__} like the preset's {default!r}")
    try:
        replace(base, **changes)
    except (ValueError, TypeError) as exc:
        raise ScheduleError(f"{method} config with {changes}: {exc}") from None
    return changes


def first_phase(method: str, config) -> tuple[Phase, int] | None:
    """Return the method's first phase and its length in ``config``, or ``None``."""
    phase = PHASES.get(method)
    return None if phase is None else (phase, int(getattr(config, phase.field)))


def recipe_for(method: str, preset: str = "demo", iters: int | None = None,
               schedule: str = "benchmark", changes: dict | None = None) -> Recipe:
    """Return the recipe of ``method`` with ``preset`` (and ``changes``) for ``iters`` iterations.

    Under the ``benchmark`` schedule a first phase longer than its share of ``iters`` is
    shortened to that share (at least 1, and a budget of 1 that leaves a first stage no
    rest is a :class:`ScheduleError`); under ``full`` the phases stay and a budget that
    ends inside the first is a :class:`ScheduleError`. Without ``iters`` (a time budget)
    nothing changes.
    """
    from generation.methods import get_method

    if schedule not in SCHEDULES:
        raise ScheduleError(f"unknown schedule {schedule!r}; choose one of "
                            f"{', '.join(SCHEDULES)} ({'; '.join(f'{k}: {v}' for k, v in SCHEDULES.items())})")
    recipe = Recipe(preset, dict(changes or {}))
    if iters is None:
        return recipe
    found = first_phase(method, recipe.config(get_method(method)))
    if found is None:
        return recipe
    phase, length = found
    if schedule == "full":
        check_budget(method, preset, iters, length)
        return recipe
    if iters * phase.share < length:
        shortened = max(1, int(iters * phase.share))
        if phase.stage and iters - shortened < 1:
            raise ScheduleError(
                f"{method} {phase.what} ({phase.field}) and needs at least 2 iterations under the "
                f"benchmark schedule (its first phase takes {phase.share:.0%} of the budget, at "
                f"least 1, and the rest trains the rest); {iters:,} leaves the rest untrained. "
                f"Give 2 iterations or more")
        recipe = Recipe(preset, {**recipe.changes, phase.field: shortened})
    return recipe


def check_budget(method: str, preset: str, iters: int, length: int) -> None:
    """Raise :class:`ScheduleError` if ``iters`` iterations end inside ``method``'s first stage."""
    phase = PHASES[method]
    if phase.stage and iters <= length:
        raise ScheduleError(
            f"{method} {phase.what} for its first {length:,} iterations ({phase.field} of the "
            f"{preset} preset); {iters:,} iterations end inside that phase. Give more than "
            f"{length:,} iterations, or schedule: benchmark (the phase then takes "
            f"{phase.share:.0%} of the budget, as compare_methods trains it)")


def departures(config) -> dict:
    """Return the switches of ``config`` that differ from its paper preset's.

    Switches are the true-or-false and named fields and the extra loss weights
    (``*_weight``): departures from the paper's method (sa_gcn's attention and
    conditioning, ODMO's ``exact_end``), not the sizes and learning rates of a smaller preset.
    """
    paper = type(config).preset("paper")
    out = {}
    for name, value in config.to_dict().items():
        switch = isinstance(value, (bool, str)) or name.endswith("_weight")
        if switch and value != getattr(paper, name):
            out[name] = value
    return out
