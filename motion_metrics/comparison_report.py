"""Turn the results of :func:`motion_metrics.comparison.run_comparison` into ``docs/RESULTS.md``.

Per data setting: how the data was split and the classifier trained, the methods'
training within the budget (per seed), our numbers (the mean over training seeds with a
95 % t interval over seeds, and beside it the 95 % interval over samples of the
evaluation protocol, named per table) with the Real values beside and the papers'
numbers in their own columns, and a paragraph on where and why we fall short of the
papers.
"""

from __future__ import annotations

import math
import shlex
from datetime import datetime
from pathlib import Path

from motion_metrics.paper_numbers import TABLES, PaperTable
from motion_metrics.protocol import MMD_PROTOCOLS

CLASSIFIER_METRICS = ("fid", "accuracy", "diversity", "multimodality")
NAMES = {"mmd_avg": "MMD_avg ↓", "mmd_seq": "MMD_seq ↓", "accuracy": "accuracy ↑",
         "fid": "FID ↓", "diversity": "diversity →", "multimodality": "multimodality →"}
SHORT = {"004_table_1": "004 T1", "003_table_1": "003 T1", "004_table_2": "004 T2",
         "000_table_1": "A2M (HumanAct12)"}
DESCRIPTIONS = {
    "h36m2d": (
        "Human3.6M in 2D: the setting of seeds 003 and 004",
        "15 joints (`h36m15_2d`, hip dropped) projected onto camera 55011271, clips of {frames} "
        "frames at {fps:.2f} Hz (our takes are at 25 fps and are resampled; the papers took "
        "every 3rd frame of the 50 Hz data), the papers' {classes} classes.",
    ),
    "h36m": (
        "Human3.6M in 3D: our choice of setting for Action2Motion's metrics",
        "17 joints (`h36m17`, metres), clips of {frames} frames at {fps:g} fps, all {classes} "
        "Human3.6M actions. Action2Motion evaluated on HumanAct12, NTU-RGB-D and CMU MoCap, not "
        "on Human3.6M; we chose this setting because that is the 3D data we have. Its HumanAct12 "
        "numbers are shown for reference only: **another dataset** (12 classes, 24 SMPL "
        "joints), another classifier and so another feature scale, so compare each method's "
        "gap to Real, not the values.",
    ),
    "demo": (
        "Synthetic demo data (a smoke test, not a result)",
        "Procedural motions of `h36m17`, {frames} frames at {fps:g} fps, {classes} actions; "
        "the paper columns are of another dataset and shown only to exercise the table.",
    ),
}


PROTOCOLS = {
    "bootstrap": ("one set of generated motions per seed, resampled with replacement within "
                  "each action in every repeat; Real compares held-out with training clips"),
    "a2m": ("Action2Motion's: a fresh set of generated motions per repeat; Real compares two "
            "draws of the held-out clips"),
}
COND_GRU = ("`cond_gru` starts every motion from the first pose of a real training clip of its "
            "action (drawn from a bank of such poses kept in its checkpoint; seed 000's baseline "
            "needs a first pose), a head start the other methods lack")


def _budget_text(result: dict) -> str:
    if result.get("iters") is not None:
        return f"{result['iters']:,} training iterations"
    return f"{result['budget']:g} s of training wall time"


def render(result: dict, command: str, beside: dict | None = None) -> str:
    """Return the Markdown of a comparison run, produced by ``command``. ``beside``: the
    files next to the output that hold another setting's run (:func:`runs_beside`), named
    instead of a command for that setting."""
    lines = ["# Results: our methods measured against the seed papers' tables", ""]
    lines += _provenance(result, command)
    lines += _not_run(result, command, beside or {})
    for setting in result["settings"]:
        lines += _setting(result, setting)
    lines += _shortfalls(result)
    return "\n".join(lines).rstrip() + "\n"


def _provenance(result: dict, command: str) -> list[str]:
    info = result["machine"]
    gpu = info["gpu"] or "no GPU"
    when = datetime.fromisoformat(result["started"]).strftime("%Y-%m-%d %H:%M UTC")
    loads = [value for value in (info.get("load"), result.get("load_at_end")) if value is not None]
    load = (f"; shared with other work (load average {loads[0]:.1f} at the start, "
            f"{loads[-1]:.1f} at the end)" if loads else "")
    entries = [entry for setting in result["settings"] for entry in setting["methods"].values()]
    reused = sum(int(entry.get("reused") or 0) for entry in entries)
    trainings = sum(len(entry.get("runs") or []) for entry in entries)
    earlier = (f" ({reused} of the {trainings} trainings were reused from `--work`, where an "
               f"earlier invocation with the same budget had finished them)" if reused else "")
    seeds = result["seeds"]
    work = {
        "training": sum(entry.get("seconds") or 0 for entry in entries),
        "fitting ODMO's modes": sum(entry.get("finish_seconds") or 0 for entry in entries),
        "checkpoint selection": sum(entry.get("select_seconds") or 0 for entry in entries),
        "sampling and evaluation": sum(entry.get("evaluate_seconds") or 0 for entry in entries),
        "classifier training": sum(setting["classifier"].get("seconds") or 0
                                   for setting in result["settings"]),
    }
    summed = ", ".join(f"{name} {seconds / 60:.1f} min" for name, seconds in work.items() if seconds)
    return [
        f"Written by `compare_methods` (`motion_metrics/comparison.py`) on {when}, in "
        f"{result['wall_seconds'] / 60:.1f} minutes of wall time{earlier}:",
        "",
        "```",
        command,
        "```",
        "",
        f"- Machine: {info['cores']} CPU cores ({info['cpu']}), {gpu}; Python {info['python']}, "
        f"torch {info['torch']}, one torch thread{load}.",
        f"- Work behind these numbers, summed over the invocations that made it: {summed}.",
        f"- Budget: **{_budget_text(result)} per method, setting and training seed** "
        + ("(the same number for every method; the iterations of a pretraining phase count) "
           if result.get("iters") is not None else "")
        + f"on one torch thread, checkpointed and resumable; ODMO's mode fitting after training "
        f"is timed apart. The preset of each method is stated per row of the training tables "
        f"(`paper`: the paper's configuration; `demo`: the method's small configuration); "
        f"their CPU seconds show how much of a core each method got on the shared machine. "
        f"**The numbers depend on this budget**: more training changes them, and the order "
        f"of the methods with them.",
        f"- Training seeds {', '.join(map(str, seeds))}: each seed trains its own model, which "
        f"draws {result['n']} motions per action with that seed (seed 003 drew 100 per class) "
        f"and is evaluated over {result['repeats']} repeats seeded by it. Each of our cells is "
        f"**the mean over the {len(seeds)} seeds' models ± the half-width of the 95 % t "
        f"interval over seeds** (t with {len(seeds) - 1} degrees of freedom × standard "
        f"deviation / √{len(seeds)}); the column after it, **± samples**, is the 95 % interval "
        f"over samples of the evaluation protocol (`motion_metrics/protocol.py`, named above "
        f"each table), averaged over the seeds. The interval over seeds includes the variation "
        f"of training; the one over samples does not. **Real** (from the first seed's "
        f"evaluation, with the protocol's interval) compares held-out clips with training "
        f"clips, as the papers' \"Real motions\" rows do.",
        f"- {_selection_text(result.get('selection'))}",
        "",
    ]


def _selection_text(selection: dict | None, short: bool = False) -> str:
    """Return which checkpoint of each training was evaluated, as a sentence (``short``: above a table)."""
    if not selection or selection.get("rule", "last") == "last":
        return "Checkpoints: the last of each training (`--select last`)."
    if short:
        return (f"Checkpoints: per seed, the lowest MMD_seq (`paper` MMD protocol, against the "
                f"training clips) of candidates every {selection['every']:,} iterations and the "
                f"last (`--select best-mmd-seq`).")
    return (f"Checkpoints: per method and seed, of the candidates kept every {selection['every']:,} "
            f"iterations within the budget and the last, the one with the lowest MMD_seq against "
            f"the training clips by the `paper` MMD protocol (`--select best-mmd-seq`, as seeds "
            f"003/004 chose theirs; {selection['n']} motions per action sampled with another seed "
            f"than the evaluated ones, {selection['repeats']} repeats); the training tables give "
            f"the iteration evaluated.")


def _with_values(parts: list[str], values: dict) -> tuple[list[str], dict]:
    """Return ``parts`` (a command's words) with the values of the options in ``values``
    (``{"--dataset": ..., "--out": ...}``; None keeps a value, and removes the option
    with its value from the words) replaced, in both the ``--name value`` and the
    ``--name=value`` forms, and the values the command had."""
    out, had, skip = [], {}, False
    for at, word in enumerate(parts):
        if skip:
            skip = False
            continue
        name, equals, value = word.partition("=")
        if name not in values:
            out.append(word)
            continue
        if not equals and at + 1 < len(parts):
            value, skip = parts[at + 1], True
        had[name] = value
        if values[name] is not None:
            out += [name, values[name]]
    return out, had


def _options(command: str) -> tuple[list[str], list[str]] | None:
    """Return the datasets of a ``compare_methods`` command and the rest of its words
    without ``--dataset``, ``--out`` and their values; None if it cannot be read."""
    try:
        parts = shlex.split(command)
    except ValueError:
        return None
    rest, had = _with_values(parts, {"--dataset": None, "--out": None})
    datasets = [name.strip() for name in had.get("--dataset", "").split(",") if name.strip()]
    return datasets, rest


def runs_beside(out) -> dict:
    """Return ``{setting: [(file name, command), ...]}`` of the results files in ``out``'s
    folder (other than ``out``) written by ``compare_methods``: the settings named by
    ``--dataset`` in the command at each file's top. Files that cannot be read are
    skipped."""
    out = Path(out)
    found = {}
    for path in sorted(out.parent.glob("*.md")):
        if not path.is_file() or path.resolve() == out.resolve():
            continue
        try:
            head = path.read_text(errors="replace")[:4000].split("```")
        except OSError:
            continue
        command = head[1].strip() if len(head) > 2 else ""
        options = _options(command) if "compare_methods" in command else None
        for name in (options or ([], []))[0]:
            found.setdefault(name, []).append((path.name, command))
    return found


def _not_run(result: dict, command: str, beside: dict) -> list[str]:
    """Return which Human3.6M settings this run left out: the file beside it that holds one
    run with this command's other options, or else the command that runs it into a file
    of its own (and the files beside it that hold it at other settings)."""
    run = [setting["dataset"] for setting in result["settings"]]
    missing = [name for name in ("h36m2d", "h36m") if name not in run]
    if not missing or not any(name.startswith("h36m") for name in run):
        return []
    ours = (_options(command) or ([], None))[1]
    same, other = {}, {}
    for name in missing:
        for file, theirs in beside.get(name, []):
            if (_options(theirs) or ([], ()))[1] == ours:
                same.setdefault(name, file)
        if name not in same and beside.get(name):
            other[name] = [file for file, _ in beside[name]]
    missing = [name for name in missing if name not in same]
    lines = [f"- Settings run: {', '.join(run)}."]
    if same:
        lines[0] += (" Run with the same options by its own command (at the top of its file): "
                     + "; ".join(f"{name} in `{file}` beside this file" for name, file in same.items())
                     + ".")
    if other:
        lines[0] += (" Run at other settings (the command at the top of its file): "
                     + "; ".join(f"{name} in " + ", ".join(f"`{file}`" for file in files)
                                 for name, files in other.items()) + ".")
    if not missing:
        return lines + [""]
    parts = shlex.split(command)
    _, had = _with_values(parts, {"--out": None})
    folder = Path(had.get("--out", "RESULTS.md")).parent
    taken = {file for files in beside.values() for file, _ in files}
    stem = "RESULTS_" + "_".join(missing)
    name, number = f"{stem}.md", 1
    while name in taken:  # a file beside holds this setting at other settings: keep it
        number += 1
        name = f"{stem}_{number}.md"
    parts, _ = _with_values(parts, {"--dataset": ",".join(missing),
                                    "--out": str(folder / name) if "--out" in had else None})
    lines[0] += (f" **Not run** {'with these options' if other else 'at this budget'} on this "
                 f"machine: {', '.join(missing)}; the same budget for "
                 f"{'it' if len(missing) == 1 else 'them'} (into a file of its own beside this "
                 f"one, with the same `--work`):")
    return lines + ["", "```", shlex.join(parts), "```", ""]


def _setting(result: dict, setting: dict) -> list[str]:
    title, data = DESCRIPTIONS.get(setting["dataset"], (f"Dataset {setting['dataset']}", ""))
    tables = [TABLES[key] for key in setting["tables"]]
    clf = setting["classifier"]
    train = setting["split"].get("train_subjects")
    lines = [f"## {title}", ""]
    if data:
        lines.append("- Data: " + data.format(frames=setting["frames"], fps=setting["fps"],
                                              classes=len(setting["actions"])))
    lines.append(
        f"- Split: {'training subjects ' + ', '.join(train) if train else 'the other clips'} "
        f"({setting['n_train']} clips) for the methods and the classifier; "
        f"{setting['split_text']} ({setting['n_test']} clips) for evaluation."
        + (" The papers trained on S1, S5, S6, S7, S8, S9 and tested on S11; our copy of "
           "Human3.6M has no S11, so S9 is held out instead (one training subject fewer)."
           if setting["dataset"].startswith("h36m") else "")
    )
    lines.append(
        f"- Classifier: A2M's GRU recogniser ({clf['preset']} preset: {clf['layers']} layers of "
        f"{clf['hidden']}, 30-d tanh features"
        + (f", a temporal convolution of {clf['temporal']} beside it" if clf.get("temporal") else "")
        + f") trained {clf['iterations']} iterations on the training clips"
        + _augmentation(clf) + "; its own "
        f"accuracy on the held-out clips is **{clf['test_accuracy']:.3f}** (on the training "
        f"clips {clf['train_accuracy']:.3f})."
        + (f" Early stopping: {clf['n_validation']} clips of a seeded share of the training "
           f"takes validate (it fits the other {clf['n_fit']}); the state of iteration "
           f"{clf['best_iteration']} is kept (validation accuracy "
           f"{clf['validation_accuracy']:.3f})"
           + (", training stopped on patience." if clf.get("stopped_early") else ".")
           if clf.get("best_iteration") is not None else "")
        + (" Seed 004's classifier has its video discriminator's architecture, so accuracies "
           "compare in tendency only." if "004_table_2" in setting["tables"] else "")
        + " The classifier variants tried, with their held-out accuracy, and real clips' MMD "
          "against the number of clips: `docs/INSTRUMENTS.md`."
    )
    lines.append("")
    lines += _confusion_table(setting)
    lines += _training_table(setting)
    main = [m for m in setting["metrics"] if any(m in t.metrics for t in tables)]
    extra = [m for m in setting["metrics"] if m not in main]
    lines += _metric_table(setting, main, [t for t in tables if t.key != "004_table_2"])
    if any(t.key == "004_table_2" for t in tables):
        lines += _per_class_table(setting, TABLES["004_table_2"])
    if extra:
        lines += [f"Also measured (the papers of this setting report no {', '.join(extra)}):", ""]
        lines += _metric_table(setting, extra, [])
    return lines


def _training_table(setting: dict) -> list[str]:
    best = (setting.get("selection") or {}).get("rule") == "best-mmd-seq"
    lines = ["Training within the budget (values per training seed, in the order of the seeds; "
             "departures: the preset's switches that the paper's method does not have):", "",
             "| method | preset | departures from the paper | parameters | iterations | "
             + ("evaluated (lowest MMD_seq) | " if best else "")
             + "train (s, wall) | train (s, CPU) | after training (s) |",
             "|---|---|---|---:|---:|" + ("---:|" if best else "") + "---:|---:|---:|"]
    for method, entry in setting["methods"].items():
        runs = [run for run in entry.get("runs") or [] if run.get("seconds") is not None]
        departures = ", ".join(f"{k}={v}" for k, v in (entry.get("departures") or {}).items()) or "none"
        if not runs:
            lines.append(f"| `{method}` | {entry['recipe']} | {departures} | | | | | |"
                         + (" |" if best else ""))
            continue
        chosen = (" / ".join("–" if run.get("chosen") is None else f"{run['chosen']:,}" for run in runs)
                  + " | ") if best else ""
        finish = [run.get("finish_seconds") for run in runs]
        lines.append(
            f"| `{method}` | {entry['recipe']} | {departures} | {entry['parameters']:,} | "
            f"{_per_seed_counts([run['iterations'] for run in runs])} | {chosen}"
            + " / ".join(f"{run['seconds']:.0f}" for run in runs) + " | "
            + " / ".join(f"{run['cpu_seconds']:.0f}" for run in runs) + " | "
            + ("" if all(value is None for value in finish) else
               " / ".join("" if value is None else f"{value:.0f}" for value in finish) + " (modes)")
            + " |"
        )
    return lines + [""]


def _per_seed_counts(values: list[int]) -> str:
    """Return per-seed iteration counts: ``N × seeds`` when all are equal."""
    if len(set(values)) == 1:
        return f"{values[0]:,} × {len(values)}"
    return " / ".join(f"{value:,}" for value in values)


def _cell(row: dict | None, digits: int = 3, key: str = "ci_seeds") -> str:
    if not row or row.get("mean") is None or not math.isfinite(row["mean"]):
        return "–"
    ci = row.get(key)
    return f"{row['mean']:.{digits}f}" + ("" if ci is None else f" ± {ci:.{digits}f}")


def _spread(row: dict | None, digits: int = 3) -> str:
    """Return the interval over samples of our row (or of Real) as ``± value``."""
    if not row or row.get("mean") is None:
        return ""
    ci = row.get("ci_samples", row.get("ci"))
    return "" if ci is None or not math.isfinite(ci) else f"± {ci:.{digits}f}"


def _first(setting: dict, metric: str) -> str | None:
    """Return the method whose mean ranks first by ``metric`` (closest to Real for → metrics)."""
    scored = {name: _mean(entry, metric) for name, entry in setting["methods"].items()
              if _mean(entry, metric) is not None}
    if not scored:
        return None
    if metric in ("diversity", "multimodality"):
        real = ((setting.get("real") or {}).get(metric) or {}).get("mean")
        if real is None:
            return None
        score = {name: abs(value - real) for name, value in scored.items()}
    elif metric == "accuracy":
        score = {name: -value for name, value in scored.items()}
    else:
        score = scored
    best = min(score, key=score.get)
    ties = [name for name, value in score.items() if value == score[best]]
    return best if len(ties) == 1 else None  # only a strict first


def _paper_cell(table: PaperTable, method: str | None, metric: str) -> str:
    row = table.real if method is None else table.row(method)
    if row is None or metric not in row.values:
        return ""
    value, ci = row.values[metric], row.ci.get(metric)
    return f"{value:.{2 if value >= 10 else 3}f}" + (f" ± {ci:.3f}" if ci is not None else "")


def _metric_table(setting: dict, metrics: list[str], tables: list[PaperTable]) -> list[str]:
    """Return a table with, per metric, our column and one column per paper table reporting it."""
    columns = []
    authors = setting.get("mmd_protocol") == "authors"
    for metric in metrics:
        columns += [(metric, None), (metric, "samples")]
        if authors and metric.startswith("mmd_"):
            columns.append((metric, "heldout"))
        columns += [(metric, table) for table in tables if metric in table.metrics]
        if metric == "accuracy" and "004_table_2" in setting["tables"]:
            columns.append((metric, TABLES["004_table_2"]))
    header = ["method"] + [(NAMES.get(m, m) + (" training clips" if authors and m.startswith("mmd_")
                                               else "") + " (± seeds, t)") if t is None else
                           "± samples" if t == "samples" else
                           "held-out clips (± seeds, t)" if t == "heldout" else SHORT.get(t.key, t.key)
                           for m, t in columns]
    name = setting.get("protocol") or "bootstrap"
    mmd = setting.get("mmd_protocol") or "heldout"
    mmd_text = (f" MMD protocol: `{mmd}` ({MMD_PROTOCOLS.get(mmd) if mmd in MMD_PROTOCOLS else mmd})."
                if any(m.startswith("mmd_") for m in metrics) else "")
    chosen = " " + _selection_text(setting.get("selection"), short=True)
    clf = setting.get("classifier") or {}
    clf_text = (f" Classifier of {', '.join(m for m in metrics if m in CLASSIFIER_METRICS)}: "
                f"`{clf.get('preset')}` preset, held-out accuracy {clf['test_accuracy']:.3f}."
                if clf.get("test_accuracy") is not None
                and any(m in CLASSIFIER_METRICS for m in metrics) else "")
    lines = [f"Protocol: `{name}` ({PROTOCOLS.get(name, name)}).{mmd_text}{clf_text}{chosen}", "",
             "| " + " | ".join(header) + " |", "|---|" + "---:|" * len(columns)]
    real = setting.get("real") or {}
    cells = [_cell(real.get(m), key="none") if t is None else _spread(real.get(m)) if t == "samples"
             else "" if t == "heldout" else _paper_cell(t, None, m) for m, t in columns]
    lines.append("| **Real** (held-out vs training clips) | " + " | ".join(cells) + " |")
    two_draws = setting.get("real_a2m") or {}
    if two_draws and any(m in two_draws for m in metrics):
        cells = [_cell(two_draws.get(m), key="none") if t is None else _spread(two_draws.get(m))
                 if t == "samples" else "" for m, t in columns]
        lines.append("| **Real** (two draws of held-out clips: A2M's definition, its tables' Real row) | "
                     + " | ".join(cells) + " |")
    firsts = {metric: _first(setting, metric) for metric in metrics}
    marked = False
    for method, entry in setting["methods"].items():
        ours = entry.get("metrics") or {}
        cells = []
        for m, t in columns:
            if t is None:
                if entry.get("error"):
                    cells.append(entry["error"].split(":")[0])
                    continue
                cell = _cell(ours.get(m))
                if method == "cond_gru" and firsts.get(m) == "cond_gru":
                    cell += " †"
                    marked = True
                cells.append(cell)
            elif t == "samples":
                cells.append("" if entry.get("error") else _spread(ours.get(m)))
            elif t == "heldout":
                cells.append("" if entry.get("error") else _cell((ours.get(m) or {}).get("heldout")))
            else:
                cells.append(_paper_cell(t, method, m))
        lines.append(f"| `{method}` | " + " | ".join(cells) + " |")
    lines.append("")
    if marked:
        lines += [f"† Ranks first here by the mean over seeds (lowest, highest accuracy, or closest to Real for → "
                  f"metrics); {COND_GRU}.", ""]
    others = []
    for table in tables:
        missing = [row for row in table.rows if row.method is None]
        if missing:
            values = "; ".join(f"{row.label} " + " / ".join(f"{row.values[m]:g}" for m in metrics
                                                           if m in row.values) for row in missing)
            others.append(f"{SHORT.get(table.key, table.key)}: {values}")
    if others:
        lines += ["Paper rows of methods not implemented here (" + " / ".join(
            NAMES[m].split(" ")[0] for m in metrics if any(m in t.metrics for t in tables)) + "): "
            + ". ".join(others) + ".", ""]
    return lines


def _augmentation(clf: dict) -> str:
    """Return how the classifier's training clips were augmented, as a clause."""
    parts = (["mirrored at random"] if clf.get("mirror") else []) + (
        [f"rotated by up to {clf['rotate']:g}°"] if clf.get("rotate") else [])
    return f" ({' and '.join(parts)})" if parts else ""


def _confusion_table(setting: dict) -> list[str]:
    """Return the classifier's held-out confusion matrix (rows true, columns predicted), if recorded."""
    confusion = setting["classifier"].get("confusion")
    if not confusion:
        return []
    actions = setting["actions"]
    lines = ["Classifier confusion on the held-out clips (rows: true action, columns: predicted):",
             "", "| true \\ predicted | " + " | ".join(actions) + " |",
             "|---|" + "---:|" * len(actions)]
    for action, row in zip(actions, confusion):
        lines.append(f"| {action} | " + " | ".join(str(n) for n in row) + " |")
    return lines + [""]


def _per_class_table(setting: dict, table: PaperTable) -> list[str]:
    actions = [a for a in table.metrics if a != "accuracy"]
    lines = ["Accuracy per class (ours: our classifier on our samples; "
             f"{SHORT[table.key]}: seed 004's classifier on its methods' samples):", "",
             "| method | " + " | ".join(actions) + " | average |",
             "|---|" + "---:|" * (len(actions) + 1)]
    real = setting["classifier"]["per_class"]
    lines.append("| **Real** (held-out clips) | " + " | ".join(
        _number(real.get(a)) for a in actions + ["accuracy"]) + " |")
    for method, entry in setting["methods"].items():
        ours = entry.get("per_class") or {}
        cells = [_number(ours.get(action)) for action in actions + ["accuracy"]]
        lines.append(f"| `{method}` | " + " | ".join(cells) + " |")
        row = table.row(method)
        if row:
            lines.append(f"| {row.label} ({SHORT[table.key]}) | " + " | ".join(
                f"{row.values[a]:.2f}" for a in actions) + f" | {row.values['accuracy']:.3f} |")
    return lines + [""]


def _number(value) -> str:
    return "–" if value is None else f"{value:.2f}"


def _mean(entry: dict, metric: str) -> float | None:
    row = (entry.get("metrics") or {}).get(metric)
    return None if not row or row.get("mean") is None else row["mean"]


def _shortfalls(result: dict) -> list[str]:
    """Return the closing section: where our numbers stand against the papers', and how the
    setting differs (what was measured and what was not, no causes guessed)."""
    lines = ["## Where we stand against the papers, and how the setting differs", ""]
    facts = []
    for setting in result["settings"]:
        facts += _setting_facts(setting)
    if any("cond_gru" in setting["methods"] for setting in result["settings"]):
        facts.append(COND_GRU[0].upper() + COND_GRU[1:] + " (how much it moves each metric was "
                     "not measured).")
    if facts:
        lines += [" ".join(facts), ""]
    presets = sorted({entry["recipe"].split(" ")[0] for setting in result["settings"]
                      for entry in setting["methods"].values()})
    lines.append(
        f"How the setting differs (facts, not measured causes): each method trained for "
        f"{_budget_text(result)} per seed on one CPU core with the {', '.join(presets)} "
        f"preset{'s' if len(presets) > 1 else ''} (the training table's column), where the papers "
        "trained full-size networks on GPUs for tens of thousands of iterations (Action2Motion: "
        "40,000 with Lie algebra, 500,000 without, seed 000's appendix; the GAN baselines "
        "pretrain a frame or pose model for 10,000 iterations in their code, here the share of "
        "the budget the training table gives). Whether more training closes the gap is "
        "measured only where a budget section follows; a single budget says nothing about it. "
        "The papers held out S11, which our copy of Human3.6M lacks, so we test on S9 and train "
        "on one subject fewer; our 2D clips are resampled from 25 fps rather than taken every "
        "3rd frame of 50 Hz; accuracy and the feature metrics use our classifier (A2M's GRU, "
        "its held-out accuracy above), not the papers' (seed 004's has its video "
        "discriminator's architecture). MMD depends on how it is measured: the papers' "
        "numbers (seeds 003/004) are each training's lowest MMD against its own training "
        "clips, while our Real row compares another subject with the training subjects, so "
        "only rows measured the same way compare. In 3D the reference numbers are of "
        "HumanAct12, another dataset, skeleton and classifier; only each method's distance "
        "from Real (of the same definition) and the order of the methods carry over."
    )
    return lines + [""]


def _setting_facts(setting: dict) -> list[str]:
    """Return sentences comparing a setting's best numbers with the papers' and with Real."""
    methods = {name: entry for name, entry in setting["methods"].items() if entry.get("metrics")}
    if not methods:
        return []
    real = setting.get("real") or {}
    dataset = setting["dataset"]
    facts = []
    if "004_table_1" in setting["tables"]:
        table = TABLES["004_table_1"]
        for metric in ("mmd_avg", "mmd_seq"):
            scored = {name: _mean(entry, metric) for name, entry in methods.items()
                      if _mean(entry, metric) is not None}
            if not scored:
                continue
            best = min(scored, key=scored.get)
            paper_best = min(table.rows, key=lambda row: row.values[metric])
            real_value = (real.get(metric) or {}).get("mean")
            facts.append(
                f"On {dataset} our best {NAMES[metric].split()[0]} (mean over seeds) is {scored[best]:.3f} "
                f"(`{best}`{_head_start(best)}), where {paper_best.label} reports {paper_best.values[metric]:g} "
                f"({table.source})" + (f" and real held-out clips score {real_value:.3f} against "
                                       f"the training clips." if real_value is not None else ".")
            )
        real_avg = (real.get("mmd_avg") or {}).get("mean")
        floor = min(row.values["mmd_avg"] for row in table.rows)
        if real_avg is not None and real_avg > floor:
            why = {"paper": " even measured against the training clips in standardised coordinates "
                            "(`paper`): the data, split and sample counts still differ from "
                            "theirs, as said below",
                   "authors": ": Real compares the held-out subject with the training subjects, "
                              "the papers' numbers a method's motions with its own training "
                              "clips (as the `authors` columns against the training clips do)",
                   }.get(setting.get("mmd_protocol"),
                         ": our MMD protocol (which motions and real clips each repeat draws and "
                         "compares) is not the papers'")
            facts.append(
                f"Real held-out clips themselves score above the paper's best method ({real_avg:.3f} "
                f"against {floor:g}), so absolute values do not carry over{why}."
            )
        facts.append(_order_sentence(methods, table, "mmd_avg"))
    if "000_table_1" in setting["tables"]:
        table = TABLES["000_table_1"]
        scored = {name: _mean(entry, "fid") for name, entry in methods.items()
                  if _mean(entry, "fid") is not None}
        real_fid = (real.get("fid") or {}).get("mean")
        two_draws = ((setting.get("real_a2m") or {}).get("fid") or {}).get("mean")
        if scored and real_fid:
            best = min(scored, key=scored.get)
            paper = table.row("a2m").values["fid"] / table.real.values["fid"]
            fact = (f"On {dataset} our best FID is {scored[best]:.3g} (`{best}`{_head_start(best)}), "
                    f"{scored[best] / real_fid:.1f}× the FID of held-out against training clips "
                    f"({real_fid:.3g}, our Real row)")
            if two_draws:
                fact += (f" and {scored[best] / two_draws:.0f}× that of two draws of the held-out "
                         f"clips ({two_draws:.3g}, the definition of Action2Motion's Real row, by "
                         f"which its FID on HumanAct12 is {paper:.0f}× its Real)")
            facts.append(fact + ".")
        facts.append(_order_sentence(methods, table, "fid"))
    real_diversity = (real.get("diversity") or {}).get("mean")
    collapsed = [name for name, entry in methods.items() if real_diversity and
                 (_mean(entry, "diversity") or real_diversity) < 0.5 * real_diversity]
    if collapsed:
        facts.append(
            f"On {dataset} " + ", ".join(f"`{name}` ({_mean(methods[name], 'diversity'):.2f})"
                                          for name in collapsed)
            + f" {'has' if len(collapsed) == 1 else 'have'} less than half the diversity of real "
            f"clips ({real_diversity:.2f}); this run does not establish why."
        )
    accuracy = {name: (methods[name].get("metrics") or {}).get("accuracy") for name in methods}
    accuracy = {name: row for name, row in accuracy.items() if row and row.get("mean") is not None}
    if len(accuracy) >= 2:
        order = sorted(accuracy, key=lambda name: -accuracy[name]["mean"])
        first, second = accuracy[order[0]], accuracy[order[1]]
        separated = (first.get("ci_seeds") is not None and second.get("ci_seeds") is not None
                     and first["mean"] - first["ci_seeds"] > second["mean"] + second["ci_seeds"])
        if separated:
            facts.append(
                f"The most recognisable samples on {dataset} are `{order[0]}`'s{_head_start(order[0])}, "
                f"at {first['mean']:.3f} accuracy (its interval over seeds clear of the next, "
                f"`{order[1]}`, {second['mean']:.3f}) against "
                f"{setting['classifier']['test_accuracy']:.3f} for real held-out clips.")
        else:
            facts.append(
                f"By accuracy on {dataset} no method is first: the highest means (`{order[0]}` "
                f"{first['mean']:.3f}, `{order[1]}` {second['mean']:.3f}) have overlapping "
                f"intervals over seeds (real held-out clips: "
                f"{setting['classifier']['test_accuracy']:.3f}).")
    return [fact for fact in facts if fact]


def _head_start(method: str) -> str:
    """Return a note for ``method`` ranking first: cond_gru starts from real poses."""
    return ", which starts from real first poses" if method == "cond_gru" else ""


def _order_sentence(methods: dict, table: PaperTable, metric: str) -> str:
    """Return whether our order of the paper's methods by ``metric`` is the paper's."""
    shared = [row for row in table.rows
              if row.method in methods and _mean(methods[row.method], metric) is not None]
    if len(shared) < 2:
        return ""
    paper = [row.method for row in sorted(shared, key=lambda row: row.values[metric])]
    ours = sorted(paper, key=lambda name: _mean(methods[name], metric))
    label = NAMES[metric].split()[0]
    rows = [(methods[name].get("metrics") or {}).get(metric) or {} for name in ours]
    overlap = any(a.get("ci_seeds") is None or b.get("ci_seeds") is None
                  or a["mean"] + a["ci_seeds"] >= b["mean"] - b["ci_seeds"]
                  for a, b in zip(rows, rows[1:]))
    caveat = (" (orders of the means over seeds; neighbours' intervals over seeds overlap, so "
              "this run does not establish the order)" if overlap else "")
    if ours == paper:
        return (f"By {label} our order of the methods {table.source} reports is the paper's "
                f"({' < '.join(ours)}){caveat}.")
    return (f"By {label} the order differs from {table.source}: ours {' < '.join(ours)}, "
            f"the paper's {' < '.join(paper)}{caveat}.")
