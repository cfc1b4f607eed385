"""Time the evaluation of 3,000 motions with every metric (20 repeats, as A2M).

    .venv/bin/python benchmarks/bench_evaluate.py [--dataset demo] [--data-root DIR]

The motions are real clips of 60 frames drawn with replacement (375 per action for the
8 demo actions), with random end targets and random modes of the real test clips so
that all ten metrics run. The
classifier is A2M's size (paper preset), trained for a few iterations: its accuracy
does not matter here, only the cost of its forward pass.
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from motion.datasets import get_dataset  # noqa: E402
from motion_metrics.recognition import train_classifier  # noqa: E402
from generation.sampling import sample_real  # noqa: E402
from motion_metrics.evaluate import METRICS, evaluate  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="demo")
    parser.add_argument("--data-root")
    parser.add_argument("--motions", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()

    dataset = get_dataset(args.dataset, args.data_root)
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        classifier = train_classifier(args.dataset, Path(folder) / "clf.pt", data_root=args.data_root,
                                      iters=20, preset="paper", progress=False)
        print(f"classifier (20 iterations, not part of the evaluation): {time.perf_counter() - start:.1f} s")
    per_action = args.motions // len(dataset.actions())
    motions = sample_real(dataset, None, per_action, frames=60, seed=1)
    rng = np.random.default_rng(0)

    def modes(clips):  # stands in for a model's clip_modes
        return np.random.default_rng(1).integers(0, 3, size=len(clips))

    targets = rng.normal(size=(len(motions), 3))

    start = time.perf_counter()
    result = evaluate(dataset, motions, classifier, METRICS, repeats=args.repeats, seed=0,
                      real_modes=modes, end_targets=targets)
    total = time.perf_counter() - start
    for metric in METRICS:
        cost = time.perf_counter()
        evaluate(dataset, motions, classifier, [metric], repeats=args.repeats, seed=0,
                 real_modes=modes, end_targets=targets)
        print(f"  {metric:<18}{time.perf_counter() - cost:6.1f} s (alone, including set-up)")
    print(f"{len(motions)} motions of {args.dataset}, 60 frames, all {len(result['metrics'])} metrics, "
          f"{args.repeats} repeats: {total:.1f} s")


if __name__ == "__main__":
    main()
