"""A budget sweep of ``compare_methods`` as Markdown: does more training help, measured.

``compare_methods --iters 250,500,1000,2000`` runs the comparison once per budget (a
method without phases trains once, to the largest budget, keeping each budget's
checkpoint; :func:`motion_metrics.comparison.start_from_shorter`). The report is the main
budget's (:func:`motion_metrics.comparison_report.render`) followed by the sweep: per
metric, each method's mean over training seeds with its 95 % t interval at every budget,
and per method whether the smallest and largest budgets' intervals separate (the only
case in which the report says that training longer changed the metric). Under the
``authors`` MMD protocol it also gives the authors' selection over checkpoints: per seed,
the lowest MMD_seq against the training clips among the budgets' checkpoints ("selected
minimum", the number SA-GCN's code reports) beside that checkpoint's MMD_seq against the
held-out clips.
"""

from __future__ import annotations

import numpy as np

from motion_metrics.comparison import t_interval
from motion_metrics.comparison_report import NAMES, render

SWEPT = ("mmd_avg", "mmd_seq", "fid", "accuracy", "diversity")
BETTER = {"mmd_avg": -1, "mmd_seq": -1, "fid": -1, "accuracy": 1}


def render_sweep(results: list[dict], command: str, main: int, beside: dict | None = None) -> str:
    """Return the Markdown of a sweep: the ``main`` budget's report (``beside`` as
    :func:`motion_metrics.comparison_report.render`), then the sweep tables."""
    by_iters = {result["iters"]: result for result in results}
    text = render(by_iters[main], command, beside).rstrip()
    lines = [text, "", "## Training budget: the same methods and seeds at "
             + ", ".join(f"{it:,}" for it in sorted(by_iters)) + " iterations", ""]
    lines += [
        f"The tables above are of {main:,} iterations. Below, every budget of this command "
        f"(methods without a first phase trained once, to the largest budget, keeping each "
        f"budget's checkpoint; methods with one trained afresh per budget, their first phase "
        f"taking its share of it). Cells: the mean over the {len(results[0]['seeds'])} training "
        f"seeds ± the 95 % t interval over seeds. A change with budget is called one only "
        f"where the smallest and the largest budget's intervals do not overlap.", ""]
    for index, setting in enumerate(results[0]["settings"]):
        settings = {it: result["settings"][index] for it, result in by_iters.items()}
        lines += _setting_sweep(settings)
    return "\n".join(lines).rstrip() + "\n"


def _row(entry: dict | None, metric: str) -> dict | None:
    return ((entry or {}).get("metrics") or {}).get(metric)


def _setting_sweep(settings: dict[int, dict]) -> list[str]:
    budgets = sorted(settings)
    first = settings[budgets[0]]
    lines = [f"### {first['dataset']}", ""]
    metrics = [m for m in SWEPT if m in first["metrics"]]
    mmd = first.get("mmd_protocol")
    for metric in metrics:
        label = NAMES.get(metric, metric)
        clf = first.get("classifier") or {}
        where = (f" (`{mmd}` MMD protocol" + (", against the training clips" if mmd == "authors" else "")
                 + ")" if metric.startswith("mmd_") else
                 f" (classifier: `{clf.get('preset')}` preset, held-out accuracy "
                 f"{clf.get('test_accuracy', float('nan')):.3f})")
        lines += [f"{label}{where}:", "", "| method | " + " | ".join(f"{b:,} it." for b in budgets)
                  + " | smallest → largest budget |", "|---|" + "---:|" * (len(budgets) + 1)]
        for method in first["methods"]:
            rows = [_row(settings[b]["methods"].get(method), metric) for b in budgets]
            cells = [_cell(row) for row in rows]
            lines.append(f"| `{method}` | " + " | ".join(cells) + f" | {_change(rows, metric)} |")
        lines.append("")
    if mmd == "authors" and "mmd_seq" in metrics:
        lines += _selected_minimum(settings)
    return lines


def _cell(row: dict | None) -> str:
    if not row or row.get("mean") is None:
        return "–"
    ci = row.get("ci_seeds")
    return f"{row['mean']:.3g}" + ("" if ci is None else f" ± {ci:.2g}")


def _change(rows: list[dict | None], metric: str) -> str:
    """Return whether the first and last budgets' intervals over seeds separate, and how."""
    a, b = rows[0], rows[-1]
    if not a or not b or a.get("mean") is None or b.get("mean") is None:
        return ""
    if a.get("ci_seeds") is None or b.get("ci_seeds") is None:
        return "no interval"
    low, high = sorted((a, b), key=lambda row: row["mean"])
    if low["mean"] + low["ci_seeds"] >= high["mean"] - high["ci_seeds"]:
        return "intervals overlap"
    rose = b["mean"] > a["mean"]
    if metric in BETTER:
        return "better" if (BETTER[metric] > 0) == rose else "worse"
    return "higher" if rose else "lower"


def _selected_minimum(settings: dict[int, dict]) -> list[str]:
    """Return the authors' selection: per seed the budget of lowest training-side MMD_seq."""
    budgets = sorted(settings)
    first = settings[budgets[0]]
    lines = ["The authors' selection over these checkpoints (SA-GCN's code keeps the lowest "
             "MMD_seq against the training clips it sees during training): per seed, the budget "
             "whose checkpoint has the lowest MMD_seq against the training clips, that minimum "
             "(the number comparable with the papers' tables), and the same checkpoint's MMD_seq "
             "against the held-out clips; mean ± 95 % t interval over seeds.", "",
             "| method | selected minimum (training clips) | same checkpoints, held-out clips | "
             "budgets chosen |", "|---|---:|---:|---|"]
    for method in first["methods"]:
        minima, heldout, chosen = [], [], []
        seeds = [run["seed"] for run in first["methods"][method].get("runs") or []]
        for seed in seeds:
            scored = {}
            for budget in budgets:
                run = _run_of(settings[budget]["methods"].get(method), seed)
                row = ((run or {}).get("metrics") or {}).get("mmd_seq") or {}
                if row.get("mean") is not None:
                    scored[budget] = (row["mean"], (row.get("heldout") or {}).get("mean"))
            if scored:
                best = min(scored, key=lambda b: scored[b][0])
                minima.append(scored[best][0])
                heldout.append(scored[best][1])
                chosen.append(f"{best:,}")
        lines.append(f"| `{method}` | {_mean_ci(minima)} | {_mean_ci(heldout)} | "
                     f"{' / '.join(chosen)} |")
    return lines + [""]


def _run_of(entry: dict | None, seed: int) -> dict | None:
    return next((run for run in (entry or {}).get("runs") or [] if run.get("seed") == seed), None)


def _mean_ci(values) -> str:
    values = [v for v in values if v is not None]
    if not values:
        return "–"
    ci = t_interval(values)
    return f"{np.mean(values):.3f}" + ("" if ci is None else f" ± {ci:.3f}")
