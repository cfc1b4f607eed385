"""Coverage of the linear mixed model's intervals when sources were trained with several seeds.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_seed_term.py [--studies 100] [--seed 1]

Each simulated study rates two equal sources (true difference 0), each trained with
``--seeds`` seeds whose checkpoints differ (a normal seed effect of SD ``--seed-sd``),
``--clips`` clips per checkpoint (clip SD ``--clip-sd``), ``--participants`` people who
each rate a random half of the clips (residual SD 1). The linear mixed model
(:func:`analysis.mixed.linear`) is fitted twice: with the ``training_seed`` column (a
random intercept per checkpoint, degrees of freedom from the seeds) and without it (the
checkpoints taken as the method: clips alone random). Prints, every 10 studies, how many
of the 95 % intervals of the difference covered 0 (docs/STATISTICS.md, "Training seeds").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import mixed


def study(rng, seeds=4, clips=4, people=30, seed_sd=0.8, clip_sd=0.3, difference=0.0):
    """Return the rows of one simulated study of sources ``a`` and ``b``."""
    rows = []
    for source, shift in (("a", difference), ("b", 0.0)):
        for seed in range(seeds):
            seed_effect = rng.normal(0, seed_sd)
            for clip in range(clips):
                clip_effect = rng.normal(0, clip_sd)
                for person in range(people):
                    if rng.random() < 0.5:
                        rows.append({"source": source, "training_seed": seed,
                                     "stimulus": f"{source}{seed}-{clip}", "pcode": f"p{person}",
                                     "rating": 3 + shift + seed_effect + clip_effect
                                     + rng.normal(0, 1)})
    return pd.DataFrame(rows)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--studies", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--seeds", type=int, default=4, help="training seeds per source")
    parser.add_argument("--clips", type=int, default=4, help="clips per checkpoint")
    parser.add_argument("--participants", type=int, default=30)
    parser.add_argument("--seed-sd", type=float, default=0.8)
    parser.add_argument("--clip-sd", type=float, default=0.3)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    covered = {"with": 0, "without": 0}
    width = {"with": [], "without": []}
    for i in range(args.studies):
        rows = study(rng, args.seeds, args.clips, args.participants, args.seed_sd, args.clip_sd)
        for name, frame in (("with", rows), ("without", rows.drop(columns="training_seed"))):
            found = mixed.linear(frame, "rating")["differences"].iloc[0]
            covered[name] += int(found.ci_low <= 0 <= found.ci_high)
            width[name].append(found.ci_high - found.ci_low)
        if (i + 1) % 10 == 0 or i + 1 == args.studies:
            print(f"{i + 1} studies: covered with the seed term {covered['with']}, without "
                  f"{covered['without']}; mean width {np.mean(width['with']):.3f} and "
                  f"{np.mean(width['without']):.3f}", flush=True)


if __name__ == "__main__":
    main()
