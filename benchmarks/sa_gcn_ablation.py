"""Which of sa_gcn's departures from the paper matter: an ablation at equal budgets.

Run (what docs/SA_GCN_COLLAPSE.md reports):

    .venv/bin/python benchmarks/sa_gcn_ablation.py --work var/sa_gcn_ablation --iters 600 \\
        --seeds 0,1,2,3,4 [--classifier var/benchmark/h36m2d/classifier.pt] [--out table.md]

Every cell trains ``sa_gcn`` on h36m2d (training subjects S1, S5, S6, S7, S8; held-out
S9, as ``compare_methods``) with the ``demo`` preset's sizes and learning rate and the
cell's switches, once per seed, for ``--iters`` iterations through the benchmark's own
training loop (:func:`generation.methods.budget.train_within_budget`). Cells cross the
initialisation (torch's ``default`` or ``he``) with the conditioning (Eq. 1 alone,
the mismatched-label term, the authors' class head), with the attention's departures
(LayerNorm on Q/K, gated residual, extra self-loop) all on and all off. Each last
checkpoint draws ``--n`` motions per action (seed = training seed), kept as ``.npz``;
with ``--classifier`` they are evaluated: accuracy, FID, feature diversity and
multimodality, APD and n-APD of the first 30 motions per action within each action
against the held-out clips, and MMD by the ``paper`` protocol. Results are cached per
cell and seed in ``--work`` (a rerun only does what is missing) and printed as a
Markdown table: the mean over seeds with a 95 % t interval, and each seed's value.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from motion.datasets import get_dataset
from motion.formats import npz
from motion_metrics.recognition import ActionClassifier, Split
from generation.methods.budget import train_within_budget
from generation.methods.schedule import Recipe
from motion_metrics.comparison import H36M_TEST, H36M_TRAIN, t_interval
from motion_metrics.evaluate import evaluate

INITS = ("default", "he")
CONDITIONING = {"eq1": {}, "mismatch": {"mismatch_weight": 1.0}, "class_head": {"class_weight": 1.0}}
ATTENTION = {"attention_on": {"qk_norm": True, "gated_residual": True, "self_loop": True},
             "attention_off": {"qk_norm": False, "gated_residual": False, "self_loop": False}}
# Everything of the demo preset that is not a departure (sizes, batch, learning rate).
BASE = {"mismatch_weight": 0.0, "class_weight": 0.0}
FEATURE_METRICS = ("accuracy", "fid", "diversity", "multimodality")
APD_PER_ACTION = 30  # motions per action for APD / n-APD, as the review measured
COLUMNS = ("accuracy", "fid", "diversity", "multimodality", "n_apd", "apd", "mmd_avg", "mmd_seq")


def cells(attention=tuple(ATTENTION)):
    """Return ``{name: config changes}`` of every cell."""
    out = {}
    for block, init, (cond, changes) in itertools.product(attention, INITS, CONDITIONING.items()):
        out[f"{block}/{init}/{cond}"] = {**BASE, **ATTENTION[block], "init": init, **changes}
    return out


def train_cell(name, changes, clips, actions, folder, iters, seed, n):
    """Train one cell with one seed (or reuse it) and return its samples."""
    recipe = Recipe("demo", changes)
    model, _ = train_within_budget("sa_gcn", clips, actions, None, folder, recipe, seed,
                                   iters=iters)
    path = folder / f"samples-seed{seed}-n{n}-it{model.iteration}.npz"
    if not path.is_file():
        npz.save(path, model.sample([a for a in actions for _ in range(n)], seed=seed))
    return npz.load(path)


def classifier_key(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def evaluate_run(data, motions, classifier, folder, seed, key, repeats):
    """Return the metrics of one run's motions, cached by the classifier's hash."""
    cache = folder / f"metrics-seed{seed}-{key}.json"
    if cache.is_file():
        return json.loads(cache.read_text())
    found = {}
    values = evaluate(data, motions, classifier, FEATURE_METRICS + ("mmd_avg", "mmd_seq"),
                      repeats, seed, mmd_protocol="paper")
    for name, row in values["metrics"].items():
        found[name] = row["mean"]
        found[f"real_{name}"] = row["real"]["mean"] if row["real"] else None
    per_action = [m for a in classifier.actions
                  for m in [x for x in motions if x.action == a][:APD_PER_ACTION]]
    values = evaluate(data, per_action, classifier, ("apd", "n_apd"), repeats, seed)
    for name, row in values["metrics"].items():
        found[name] = row["mean"]
        found[f"real_{name}"] = row["real"]["mean"] if row["real"] else None
    cache.write_text(json.dumps(found, indent=1))
    return found


def table(results: dict, seeds) -> str:
    """Return the Markdown table: per cell the mean ± t interval over seeds of each metric."""
    head = "| cell | " + " | ".join(COLUMNS) + " |"
    lines = [head, "|---|" + "---:|" * len(COLUMNS)]
    real = next(iter(results.values()))[seeds[0]] if results else {}
    lines.append("| **Real** (held-out vs training clips) | " + " | ".join(
        f"{real.get('real_' + c):.3g}" if real.get("real_" + c) is not None else "" for c in COLUMNS) + " |")
    for name, runs in results.items():
        row = []
        for column in COLUMNS:
            values = [runs[s][column] for s in seeds if runs.get(s) and runs[s].get(column) is not None]
            if not values:
                row.append("")
                continue
            ci = t_interval(values)
            row.append(f"{np.mean(values):.3g}" + (f" ± {ci:.2g}" if ci is not None else "")
                       + " (" + " / ".join(f"{v:.3g}" for v in values) + ")")
        lines.append(f"| `{name}` | " + " | ".join(row) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", required=True, type=Path)
    parser.add_argument("--iters", type=int, default=600)
    parser.add_argument("--seeds", default="0,1,2,3,4")
    parser.add_argument("--n", type=int, default=50, help="motions per action to sample")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--attention", default=",".join(ATTENTION),
                        help="blocks to run: attention_on, attention_off")
    parser.add_argument("--cells", help="only these cells, e.g. attention_off/he/eq1,...")
    parser.add_argument("--classifier", type=Path, help="evaluate with this classifier checkpoint")
    parser.add_argument("--out", type=Path, help="write the table (and results.json beside it)")
    parser.add_argument("--evaluate-only", action="store_true",
                        help="evaluate the runs already trained, train none")
    args = parser.parse_args()
    torch.set_num_threads(1)
    seeds = [int(s) for s in args.seeds.split(",")]
    data = get_dataset("h36m2d")
    split = Split(test_subjects=H36M_TEST, train_subjects=H36M_TRAIN)
    train, _ = split.divide(data.clips())
    actions = data.actions()
    classifier = ActionClassifier.load(args.classifier) if args.classifier else None
    key = classifier_key(args.classifier) if args.classifier else None
    results = {}
    chosen = cells(args.attention.split(","))
    if args.cells:
        chosen = {name: chosen[name] for name in args.cells.split(",")}
    for name, changes in chosen.items():
        folder = args.work / args.iters.__str__() / name.replace("/", "-")
        results[name] = {}
        for seed in seeds:
            if args.evaluate_only:
                done = folder / f"samples-seed{seed}-n{args.n}-it{args.iters}.npz"
                if not done.is_file():
                    continue
            motions = train_cell(name, changes, train, actions, folder, args.iters, seed, args.n)
            if classifier is not None:
                results[name][seed] = evaluate_run(data, motions, classifier, folder, seed, key,
                                                   args.repeats)
            print(f"{name} seed {seed}: " + (", ".join(
                f"{k} {v:.3g}" for k, v in results[name].get(seed, {}).items()
                if v is not None and not k.startswith("real_")) or "trained"), flush=True)
    if classifier is not None:
        accuracy = classifier.test_accuracy
        text = (f"Classifier: `{args.classifier.name}`, held-out accuracy "
                + (f"{accuracy:.3f}" if accuracy is not None else "not recorded")
                + f"; {args.iters} iterations per cell and seed.\n\n" + table(results, seeds))
        print(text)
        if args.out:
            args.out.write_text(text + "\n")
            args.out.with_suffix(".json").write_text(json.dumps(
                {name: {str(s): v for s, v in runs.items()} for name, runs in results.items()},
                indent=1))


if __name__ == "__main__":
    main()
