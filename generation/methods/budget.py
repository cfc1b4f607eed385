"""Train a method for a budget of iterations or seconds, resumably: the project's one training loop.

:func:`train_within_budget` is what ``compare_methods`` and study builds train with
(and ``manage.py train`` through :func:`generation.methods.training.train_on_dataset`):
a checkpoint and a JSON record of seconds and iterations beside it, reused when the same
method version, recipe, seed and clips ask again, resumed when interrupted.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from generation.methods.base import Method, MethodError
from generation.methods.schedule import Recipe

# Training runs as one call per resume; this many iterations is never reached.
UNBOUNDED = 10**9


class _BudgetSpent(Exception):
    """Raised inside a training step once the time or iteration budget is spent."""


@contextmanager
def deadline(model: Method, seconds: float | None, on_step: Callable[[], None],
             iters: int | None = None):
    """Make ``model``'s training steps raise :class:`_BudgetSpent` once the budget is spent.

    The budget is ``seconds`` from now, or ``iters`` iterations in all (the model's
    iteration counter). Rather than training in chunks (each re-encodes the clips, which
    takes seconds for a2m), one ``fit`` runs until a step finds the budget spent. The
    check happens before the step, when the model is consistent (its iteration counter
    counts finished steps), so ``on_step`` may save it. Methods trained in phases (a
    pretrained pose or frame model) count the iterations of every phase.
    """
    end = None if seconds is None else time.perf_counter() + seconds
    step = model.train_step

    def timed_step(batch, generator):
        if ((end is not None and time.perf_counter() >= end)
                or (iters is not None and model.iteration >= iters)):
            raise _BudgetSpent
        on_step()
        return step(batch, generator)

    model.train_step = timed_step
    try:
        yield
    except _BudgetSpent:
        pass
    finally:
        del model.train_step


def read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def write_json(path: Path, values: dict) -> None:
    """Write ``values`` beside ``path`` and rename, so a crash never leaves half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    partial.write_text(json.dumps(values, indent=2, allow_nan=False, default=_plain) + "\n")
    os.replace(partial, path)


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def train_within_budget(method: str, clips, actions: Sequence[str], budget: float | None,
                        folder: Path, recipe: Recipe, seed: int = 0,
                        checkpoint_every: float = 15.0,
                        on_tick: Callable[[str], None] | None = None,
                        iters: int | None = None, stem: str | None = None,
                        keep_every: int | None = None,
                        extra_signature: dict | None = None) -> tuple[Method, dict]:
    """Train ``method`` on ``clips`` for ``iters`` iterations, or ``budget`` seconds, in all.

    Give one of ``budget`` (seconds of wall time) and ``iters``. The checkpoint
    ``folder/<method>-seed<seed>.pt`` and its record ``.json`` (seconds, CPU seconds,
    iterations) resume an interrupted run; a model whose record says the budget is spent
    is loaded and returned as it is. Another recipe, config (a changed default included),
    method version, seed or data starts afresh. Methods with their own ``fit`` (ODMO fits
    its modes there) get one call of it with no iterations at the end, timed apart as
    ``finish_seconds``. ``stem`` names the files (default ``<method>-seed<seed>``);
    ``keep_every`` keeps a candidate checkpoint (unfinished) every that many iterations
    in the folder :func:`candidate_path` names; ``extra_signature`` (e.g. how candidates
    are chosen) joins what decides whether earlier work is reused.

    This is the one training loop of the project: ``compare_methods``, study builds and
    ``manage.py train`` run it, so the same recipe, seed and clips give the same weights.
    """
    if (budget is None) == (iters is None):
        raise MethodError("give either a time budget or a number of iterations, not both")
    from generation.methods import get_method

    cls = get_method(method)
    stem = stem or f"{method}-seed{seed}"
    checkpoint, record_path = folder / f"{stem}.pt", folder / f"{stem}.json"
    first = clips[0]
    # The full config and the method's version: a changed default or network retrains.
    signature = {"method": method, "version": cls.version, "preset": recipe.preset,
                 "changes": recipe.changes, "config": recipe.config(cls).to_dict(), "seed": seed,
                 "skeleton": first.skeleton, "frames": first.frames, "fps": first.fps,
                 "actions": list(actions), "clips": len(clips)}
    if extra_signature:  # (a plain run's signature is as it was before, so old work counts)
        signature.update(extra_signature)
    record = read_json(record_path)
    if (record.get("signature") == json.loads(json.dumps(signature, default=_plain))
            and checkpoint.is_file() and (iters is None or record.get("iterations", 0) <= iters)):
        model = cls.load(checkpoint)
    else:  # another signature, or trained past the iterations asked: start afresh
        record = {"signature": signature, "seconds": 0.0, "cpu_seconds": 0.0, "iterations": 0,
                  "finished": False}
        model = cls(recipe.config(cls), first.skeleton, list(actions), first.fps, first.frames)
        shutil.rmtree(candidate_path(folder, stem, 0).parent, ignore_errors=True)

    def keep_candidate():
        """Keep the model as a candidate if its iteration is one (and none is kept yet)."""
        if keep_every and model.iteration and model.iteration % keep_every == 0:
            path = candidate_path(folder, stem, model.iteration)
            if not path.is_file():
                model.save(path)

    record["budget"], record["iters"] = budget, iters
    if iters is None:
        remaining = budget - record["seconds"]
        todo = remaining > 0
    else:
        remaining = None
        todo = model.iteration < iters
    record["reused"] = not todo and record["finished"]
    if todo:
        record["finished"] = False
        wall, cpu = time.perf_counter(), time.process_time()
        spent, spent_cpu = record["seconds"], record["cpu_seconds"]
        last = {"save": wall, "tick": 0.0}
        goal = f"{budget:g} s" if iters is None else f"{iters} it"

        def note():
            """Bring the record up to date with the time spent so far."""
            record["seconds"] = spent + time.perf_counter() - wall
            record["cpu_seconds"] = spent_cpu + time.process_time() - cpu
            record["iterations"] = model.iteration

        def on_step():
            keep_candidate()
            now = time.perf_counter()
            if now - last["save"] >= checkpoint_every:
                note()
                model.save(checkpoint)
                write_json(record_path, record)
                last["save"] = now
            if on_tick and now - last["tick"] >= 1.0:
                on_tick(f"seed {seed}: {spent + now - wall:.0f} s, {model.iteration} it of {goal}")
                last["tick"] = now

        with deadline(model, remaining, on_step, iters):
            model.fit(clips, UNBOUNDED, seed=seed, progress=False)
        note()
        keep_candidate()
        model.save(checkpoint)
        write_json(record_path, record)
    if not record["finished"]:
        if type(model).fit is not Method.fit:
            start = time.perf_counter()
            model.fit(clips, 0, seed=seed, progress=False)
            record["finish_seconds"] = time.perf_counter() - start
            model.save(checkpoint)
        record["finished"] = True
        record.pop("evaluation", None)
        write_json(record_path, record)
    record["parameters"] = model.n_parameters
    return model, record


def candidate_path(folder: Path, stem: str, iteration: int) -> Path:
    """Return where the run ``stem`` keeps its candidate checkpoint of ``iteration``."""
    return folder / f"{stem}.candidates" / f"it{iteration}.pt"
