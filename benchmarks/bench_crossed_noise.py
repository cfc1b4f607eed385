"""How often the crossed bootstrap counts single answers' noise, by clips per trial.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_crossed_noise.py \\
        [--units 4000] [--participants 200] [--clips 20] [--replicates 2000] [--studies 20]

Each simulated table has ``--units`` trials of ``k`` clips (k = 1, 2, 4: a rating, a pair,
a set of four), one clip from each of ``k`` sources of ``--clips`` clips each, shared by
``--participants`` people; a trial's value is its clips' effects (normal, SD
``--clip-sd``, each value of the list) plus its answer's noise (normal, SD 1), and the
statistic is the mean value (a :class:`analysis.crossed.Linear` statistic, as shares and
the worth models' counts are). :func:`analysis.crossed.bootstrap` gives ``V_p``, ``V_c``
and ``V_obs``; printed per ``k`` and clip SD, as means over ``--studies`` tables (each
row its own seeds) and times the number of trials (so that the answers' noise alone is
1): each scheme's variance, the combined ``V`` the intervals use, the true variance of
the mean (noise ``1`` plus ``k`` sources' clip means), the width of the interval against
the true one (the mean over tables of each table's ratio, ± 1.96 standard errors),
and the variance of a trial's clips' weight in the clips' bootstrap (the product of
``k`` clip counts, each of mean 1 and variance ``(m - 1) / m``: ``((2m - 1) / m)^k - 1``),
which is how many times ``V_c`` holds the noise when a trial's clips come from different
sources, as here (docs/STATISTICS.md, "How often the clips' bootstrap counts the
answers' noise").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy import sparse

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import crossed

SCHEMES = ("participants", "clips", "observations", "total")


def table(k: int, rng, units=4000, participants=200, clips=20, clip_sd=0.0):
    """Return the :class:`crossed.Design` and the trials' values of one simulated table."""
    strata = np.repeat(np.arange(k), clips)
    shown = np.stack([rng.integers(0, clips, units) + j * clips for j in range(k)], axis=1)
    people = np.arange(units) % participants
    cells = np.unique(np.sort(shown, axis=1), axis=0, return_inverse=True)[1].ravel()
    effects = rng.normal(0.0, clip_sd, k * clips)
    values = rng.normal(0.0, 1.0, units) + effects[shown].sum(axis=1)
    return crossed.Design(people, shown, strata, cells), values


def variances(design: crossed.Design, values, replicates: int, seed: int) -> dict:
    """Return each scheme's variance of the mean of ``values`` and the combined ``V``."""
    matrix = sparse.csr_matrix(np.stack([values, np.ones(len(values))], axis=1))
    mean = crossed.Linear(matrix, lambda sums: (sums[:, 0] / sums[:, 1])[:, None])
    config = SimpleNamespace(bootstrap=replicates, seed=seed, random_clips=True)
    found = crossed.bootstrap(design, mean, config).variances()
    return {scheme: float(np.ravel(found[scheme])[0]) for scheme in SCHEMES}


def measure(k: int, clip_sd: float, studies=20, units=4000, participants=200, clips=20,
            replicates=2000, first_seed=0) -> dict:
    """Return the mean over ``studies`` tables of each variance times ``units``, the true
    one, the width ratio (mean and 1.96 standard errors over tables) and the clips' weight
    variance."""
    rows = []
    for seed in range(first_seed, first_seed + studies):
        design, values = table(k, np.random.default_rng(seed), units, participants, clips, clip_sd)
        rows.append(variances(design, values, replicates, seed))
    found = {scheme: units * float(np.mean([row[scheme] for row in rows])) for scheme in SCHEMES}
    truth = 1.0 + units * k * clip_sd ** 2 / clips
    widths = np.sqrt(np.array([row["total"] for row in rows]) * units / truth)
    return {"k": k, "clip_sd": clip_sd, **found, "truth": truth,
            "width": float(widths.mean()),
            "width_error": (float(1.96 * widths.std(ddof=1) / np.sqrt(len(widths)))
                            if len(widths) > 1 else 0.0),
            "weight_variance": ((2 * clips - 1) / clips) ** k - 1}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", type=int, default=4000)
    parser.add_argument("--participants", type=int, default=200)
    parser.add_argument("--clips", type=int, default=20, help="clips per source")
    parser.add_argument("--clip-sd", default="0,0.1,0.3", help="clip SDs, comma-separated")
    parser.add_argument("--replicates", type=int, default=2000)
    parser.add_argument("--studies", type=int, default=20)
    args = parser.parse_args(argv)
    print("| clips per trial (k) | clip SD | V_p | V_c | V_obs | V (intervals) | true | "
          "width / true width | clips' weight variance |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for k in (1, 2, 4):
        for clip_sd in (float(value) for value in args.clip_sd.split(",")):
            row = measure(k, clip_sd, args.studies, args.units, args.participants, args.clips,
                          args.replicates, first_seed=100_000 * k + round(1000 * clip_sd) * 100)
            print(f"| {k} | {clip_sd:g} | {row['participants']:.2f} | {row['clips']:.2f} | "
                  f"{row['observations']:.2f} | {row['total']:.2f} | {row['truth']:.2f} | "
                  f"{row['width']:.2f} ± {row['width_error']:.2f} | {row['weight_variance']:.2f} |",
                  flush=True)


if __name__ == "__main__":
    main()
