"""Held-out accuracy of action-classifier variants: what chose the metrics' classifier.

Run (what docs/RESULTS.md reports):

    .venv/bin/python benchmarks/bench_classifier.py --dataset h36m2d --work var/classifiers \\
        [--variants paper,mirror,...] [--iters 5000]

Each variant is a :class:`motion_metrics.recognition.ClassifierConfig` (a preset and changes,
:data:`VARIANTS`) trained by :func:`motion_metrics.recognition.train_classifier` on the
benchmark's training subjects (S1, S5, S6, S7, S8 of Human3.6M; S9 held out) with early
stopping on a validation share of the training takes; ``patience`` is the number of
validation measurements (every 50 iterations) without improvement before it stops.
Finished variants are reused from ``--work``. Prints a Markdown table of validation and
held-out accuracy, iterations and seconds per variant.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from motion_metrics.recognition import ClassifierConfig, train_classifier
from motion_metrics.comparison import H36M_TEST, H36M_TRAIN

# name -> (config fields, patience)
VARIANTS = {
    "paper": ({}, 10),
    "paper-patience30": ({}, 30),
    "mirror": ({"mirror": True}, 10),
    "mirror-rotate10": ({"mirror": True, "rotate": 10.0}, 10),
    "temporal64": ({"temporal": 64}, 10),
    "mirror-rotate20": ({"mirror": True, "rotate": 20.0}, 10),
    "mirror-rotate10-patience20": ({"mirror": True, "rotate": 10.0}, 20),
    "temporal64-mirror-rotate10": ({"temporal": 64, "mirror": True, "rotate": 10.0}, 10),
}


def run_variant(name, dataset, work: Path, iters: int, seed: int) -> dict:
    """Train one variant (or read its record) and return its accuracies."""
    changes, patience = VARIANTS[name]
    record = work / dataset / f"{name}-seed{seed}.json"
    if record.is_file():
        return json.loads(record.read_text())
    start = time.perf_counter()
    config = ClassifierConfig(**changes)
    model = train_classifier(dataset, record.with_suffix(".pt"), subjects=H36M_TRAIN,
                             test_subjects=H36M_TEST, iters=iters, config=config, seed=seed,
                             progress=False, patience=patience)
    found = {"variant": name, "config": config.to_dict(), "patience": patience,
             "seconds": time.perf_counter() - start, "iterations": model.iteration,
             "best_iteration": model.best_iteration, "validation": model.validation_accuracy,
             "heldout": model.test_accuracy, "train": model.train_accuracy,
             "stopped_early": model.stopped_early}
    record.write_text(json.dumps(found, indent=1))
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="h36m2d")
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--iters", type=int, default=5000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    (args.work / args.dataset).mkdir(parents=True, exist_ok=True)
    print(f"| classifier ({args.dataset}) | config | patience | iterations (kept) | validation "
          f"accuracy | held-out accuracy (S9) | seconds |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name in args.variants.split(","):
        row = run_variant(name, args.dataset, args.work, args.iters, args.seed)
        changed = {k: v for k, v in row["config"].items() if ClassifierConfig().to_dict()[k] != v}
        print(f"| {name} | {', '.join(f'{k}={v}' for k, v in changed.items()) or 'paper'} | "
              f"{row['patience']} | {row['iterations']} ({row['best_iteration']}) | "
              f"{row['validation']:.3f} | {row['heldout']:.3f} | {row['seconds']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
