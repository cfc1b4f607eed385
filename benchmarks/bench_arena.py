"""Judgements a source added to a standing arena needs to reach the leaderboard's
precision, against a balanced re-run of every source, side by side.

    .venv/bin/python benchmarks/bench_arena.py [--studies 20] [--width 0.7] [--json out.json]

Each simulated arena starts as the adaptive pairwise study of ``bench_adaptive.py``
(8 sources of strengths :data:`~benchmarks.bench_adaptive.STRENGTHS`, ``--clips`` random
clips per source of SD ``--clip-sd``, ``--trials`` pairs per participant, the adaptive
design aimed at the order, recomputed every ``--every`` judgements, every clip shown
``--min-showings`` times first) and runs until its leaderboard is precise: every
difference of neighbours in the estimated order has a 95 % interval at most ``--width``
wide (the interval of ``bench_adaptive.intervals``: the larger of the sandwich, clustered
by participant and clip, and the steady one). A ninth source then joins, of a strength
drawn uniformly from ``--new-low`` to ``--new-high`` (among the others), and is counted
until its own differences to its neighbours above and below in the estimated order reach
that width:

- ``arena adaptive``: the arena goes on with every answer so far, its adaptive design
  (as ``arena add`` leaves it: the same target, the new source in its posterior with no
  comparisons, so the widest);
- ``arena balanced``: the arena goes on with every answer so far, but every pair of the
  nine sources equally likely (the value of keeping the answers, without the design);
- ``re-run balanced (new source)``: a fresh balanced study of the nine sources, stopped
  as soon as the new source's differences reach the width;
- ``re-run balanced (whole order)``: the same study run until every neighbour difference
  reaches it: what a fixed-design leaderboard pays to publish the new order at the
  leaderboard's precision.

Reported: judgements after the source joined (mean, median, relative to the whole-order
re-run), the share of studies reaching the width within ``--budget``, and the coverage
of the new source's true differences (of infinitely many clips and judgements) by the
intervals at the stop.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.special import expit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import adaptive  # noqa: E402
from benchmarks.bench_adaptive import STRENGTHS, intervals, truth  # noqa: E402

DESIGNS = ("arena adaptive", "arena balanced", "re-run balanced (new source)",
           "re-run balanced (whole order)")


class Run:
    """Answers of one simulated study so far, and the state of its design."""

    def __init__(self, n_sources, clips, quality, rng, answers, participant=-1):
        self.k = n_sources
        self.clips = clips
        self.quality = quality
        self.rng = rng
        self.answers = answers
        self.data = [[], [], [], [], []]
        self.shown = Counter()
        self.participant = participant
        self.queue = []
        self.dist = adaptive.balanced(n_sources)

    def grow(self, n_sources, clips):
        """A source joins: new participants plan from a distribution over every source."""
        self.k, self.clips, self.queue = n_sources, clips, []
        self.dist = adaptive.balanced(n_sources)

    def judge(self, args):
        if not self.queue:
            self.participant += 1
            self.queue = adaptive.plan_pairs(self.dist, args.trials, self.clips, self.shown,
                                             self.rng, min_showings=args.min_showings)
        left, right = self.queue.pop(0)
        left_wins = self.answers.random() < expit(self.quality[left] - self.quality[right])
        w, l = (left, right) if left_wins else (right, left)
        for column, value in zip(self.data, (w // args.clips, l // args.clips, w, l,
                                             self.participant)):
            column.append(value)

    def look(self, args, adaptive_design, seed):
        theta, half, steady = intervals(self.k, self.data, args.clips)
        half = np.maximum(half, steady)
        if adaptive_design:
            post = adaptive.posterior(self.k, self.data[0], self.data[1])
            self.dist = adaptive.distribution(post, "order", floor=args.floor,
                                              sharpness=args.sharpness, focus=args.focus,
                                              seed=seed)
        return theta, half


def neighbours(theta, source):
    """Return the pairs of ``source`` and its neighbours in the order of ``theta``."""
    order = list(np.argsort(-theta))
    at = order.index(source)
    return [(source, order[j]) for j in (at - 1, at + 1) if 0 <= j < len(order)]


def whole_order(theta, source):
    order = np.argsort(-theta)
    return list(zip(order[:-1], order[1:]))


def until(run, args, pairs_of, adaptive_design, seed, new):
    """Judge until the pairs ``pairs_of(theta, new)`` are all at most the width; return
    the judgements it took (None past the budget) and the intervals at the stop."""
    start = len(run.data[0])
    while len(run.data[0]) - start < args.budget:
        run.judge(args)
        n = len(run.data[0])
        if n % args.every:
            continue
        theta, half = run.look(args, adaptive_design, seed + n)
        pairs = pairs_of(theta, new)
        if max(2 * half[a, b] for a, b in pairs) <= args.width:
            return n - start, theta, half, pairs
    return None, None, None, []


def run_arena(args, seed):
    """Return per design the judgements after the new source joined and the coverage."""
    rng = np.random.default_rng(seed)
    k = len(STRENGTHS)
    new_strength = rng.uniform(args.new_low, args.new_high)
    strengths = np.append(STRENGTHS, new_strength)
    quality = np.repeat(strengths, args.clips) + rng.normal(0, args.clip_sd, (k + 1) * args.clips)
    true = truth(strengths, args.clip_sd)
    old = {s: list(range(s * args.clips, (s + 1) * args.clips)) for s in range(k)}
    every = {**old, k: list(range(k * args.clips, (k + 1) * args.clips))}
    # The standing arena, run to the leaderboard's precision with its adaptive design.
    standing = Run(k, old, quality, random.Random(seed), np.random.default_rng(seed + 10_000))
    before, *_ = until(standing, args, whole_order, True, seed, 0)
    out = {"before": before, "strength": float(new_strength)}
    for design in DESIGNS:
        if design.startswith("arena"):
            run = Run(k, old, quality, random.Random(seed + 1), None)
            run.answers = np.random.default_rng(seed + 20_000)
            run.data = [list(column) for column in standing.data]
            run.shown = Counter(standing.shown)
            run.participant = standing.participant
            run.grow(k + 1, every)
            if design == "arena adaptive":  # arena add recomputes the distribution at once
                run.look(args, True, seed)
        else:
            run = Run(k + 1, every, quality, random.Random(seed + 2),
                      np.random.default_rng(seed + 30_000))
        pairs_of = whole_order if design.endswith("(whole order)") else neighbours
        n, theta, half, pairs = until(run, args, pairs_of, design == "arena adaptive",
                                      seed + 7, k)
        mine = [(a, b) for a, b in neighbours(theta, k)] if n is not None else []
        covered = [bool(abs((theta[a] - theta[b]) - (true[a] - true[b])) <= half[a, b])
                   for a, b in mine]
        out[design] = {"n": n, "covered": covered}
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--studies", type=int, default=20)
    parser.add_argument("--width", type=float, default=0.7)
    parser.add_argument("--every", type=int, default=100)
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--clips", type=int, default=20)
    parser.add_argument("--clip-sd", type=float, default=0.3)
    parser.add_argument("--min-showings", type=int, default=2)
    parser.add_argument("--new-low", type=float, default=-0.5)
    parser.add_argument("--new-high", type=float, default=1.5)
    parser.add_argument("--budget", type=int, default=20000)
    parser.add_argument("--floor", type=float, default=adaptive.FLOOR)
    parser.add_argument("--sharpness", type=float, default=2.0)
    parser.add_argument("--focus", type=float, default=2.0)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    results = [run_arena(args, args.first_seed + study) for study in range(args.studies)]
    seconds = time.perf_counter() - started
    base = np.mean([r[DESIGNS[-1]]["n"] for r in results if r[DESIGNS[-1]]["n"] is not None])
    rows = []
    for design in DESIGNS:
        ns = [r[design]["n"] for r in results]
        reached = [n for n in ns if n is not None]
        covered = [c for r in results for c in r[design]["covered"]]
        mean = float(np.mean(reached)) if reached else float("nan")
        rows.append({"design": design, "reached": f"{len(reached)}/{len(ns)}", "mean": mean,
                     "median": float(np.median(reached)) if reached else float("nan"),
                     "vs_rerun": mean / base - 1,
                     "coverage": float(np.mean(covered)) if covered else float("nan"),
                     "intervals": len(covered)})
    standing = [r["before"] for r in results if r["before"] is not None]
    print(f"{args.studies} arenas: 8 sources run to width {args.width} (mean "
          f"{np.mean(standing):.0f} judgements), then a ninth source of strength "
          f"U({args.new_low}, {args.new_high}); {args.clips} clips per source (clip SD "
          f"{args.clip_sd}), {args.trials} pairs per participant, looks every {args.every}; "
          f"{seconds:.0f} s")
    print("| design | reached | mean judgements after the source joined | median | "
          "vs whole-order re-run | coverage of the new source's differences (intervals) |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        print(f"| {row['design']} | {row['reached']} | {row['mean']:.0f} | {row['median']:.0f} | "
              f"{row['vs_rerun']:+.0%} | {row['coverage']:.3f} ({row['intervals']}) |")
    if args.json:
        args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                         "rows": rows, "studies": results}, indent=1))


if __name__ == "__main__":
    main()
