"""Judgements an adaptive pairwise design needs against a balanced one, side by side.

    .venv/bin/python benchmarks/bench_adaptive.py [--studies 20] [--every 100]
        [--top-width 0.6] [--order-width 0.7] [--budget 20000] [--targets top_two,order]
        [--designs balanced,top_two,order,order_batch] [--interval larger|sandwich]
        [--stop-on larger|information|sandwich] [--rules reported,app] [--crossed
        [--bootstrap 1000]] [--json out.json]

Each simulated study has 8 sources with a spread of Bradley-Terry strengths
(:data:`STRENGTHS`), ``--clips`` clips per source whose qualities vary about their
source's (``--clip-sd``, logit scale: clips are random), and participants who judge
``--trials`` pairs each (left wins with probability ``sigmoid(q_left - q_right)``, as
``analysis.pairwise`` simulates). Three designs draw the same studies (same strengths and
clips, fresh answers):

- ``balanced``: every pair of sources equally likely;
- ``adaptive top_two`` and ``adaptive order``: :func:`analysis.adaptive.distribution`
  aiming at the top two or at the whole order, recomputed every ``--every`` judgements
  (every clip shown ``--min-showings`` times first, no participant seeing a pair of clips
  twice, positions counterbalanced per participant: :func:`analysis.adaptive.plan_pairs`);
- ``adaptive top_two_batch`` and ``adaptive order_batch``: the same targets, each look's
  next ``--every`` comparisons planned as one batch (``adaptive.batch``:
  :func:`analysis.adaptive.batch_counts`).

Every ``--every`` judgements (a look) two 95 % intervals of each source difference are
computed, both treating participants and clips as random but in closed form, so that
they can be computed at every look (the study's analysis, ``analysis.crossed``, bootstraps
instead; it is not what is measured here):

- the sandwich: the Bradley-Terry fit (weak prior) with a sandwich variance clustered by
  participant and by clip (a comparison belongs to both its clips; CR1 factors), a t
  interval with the fewer of the participants' and the two sources' clips' degrees of
  freedom;
- the steady one: the model's variance plus one clip variance pooled over every pair of
  sources (moments of the sandwich's excess) times how much each source leans on single
  clips (the sum of squared shares of its clips' showings); it barely depends on the
  luck of the answers.

A study stops, per target, at the first look where the interval reported there (the larger
of the two, ``--interval``) of the top-two difference (the two sources estimated best), or
of every difference of neighbours in the estimated order, is at most the target width: so
every design stops at the same width. ``--stop-on information`` stops on the steady width
alone (the reported interval may then be wider than the target), ``--stop-on sandwich`` on
the sandwich's alone, which selects looks where the sandwich happens to be small and so
undercovers. ``--rules app`` stops instead by the app's stopping rule
(``study.stop_when: {interval_width: W}``, :func:`analysis.adaptive.stop_state`: the steady
interval alone); ``--rules reported,app`` stops a copy of each simulated study by each
rule (the answers do not depend on the rule). ``--crossed`` also computes, at each stop,
the study's own intervals (the pairwise analysis's crossed bootstrap of participants and
clips, :func:`crossed_intervals`) and their coverage. Reported per rule, design and target:
the judgements needed (median, mean, and the mean relative to balanced), the share of
studies reaching the target within ``--budget``, the coverage of the true differences
(those of infinitely many clips and judgements, balanced: :func:`truth`) by the reported
intervals at the stopping time, the share of studies whose intervals all covered, and the
mean reported width at the stop.
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
from scipy import stats
from scipy.special import expit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import adaptive, worth  # noqa: E402

STRENGTHS = np.array([1.6, 1.3, 1.0, 0.8, 0.5, 0.2, -0.3, -1.0])


def truth(strength, clip_sd):
    """Return the centred Bradley-Terry worths of infinitely many judgements of infinitely
    many clips per source (balanced over pairs): the estimand of every design."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(40)
    weights = weights / weights.sum()
    k = len(strength)
    orders, counts = [], []
    for i in range(k):
        for j in range(k):
            if i != j:
                p = weights @ expit(strength[i] - strength[j] + np.sqrt(2) * clip_sd * nodes)
                orders.append([i, j])
                counts.append(p * 1e6)
    return worth.fit(np.array(orders), np.array(counts), k, prior=0)


def intervals(n_sources, data, clips_per_source, confidence=0.95):
    """Return the fit, and the ``(K, K)`` matrix of interval half-widths of ``a - b``."""
    winner, loser, clip_w, clip_l, who = (np.asarray(c) for c in data)
    post = adaptive.posterior(n_sources, winner, loser)
    theta = post.mean
    p = expit(theta[winner] - theta[loser])
    g = np.zeros((len(winner), n_sources))
    rows = np.arange(len(winner))
    g[rows, winner] = 1 - p
    g[rows, loser] = -(1 - p)
    n_clips = int(max(clip_w.max(), clip_l.max())) + 1

    def meat(keys, n_keys):
        sums = np.zeros((n_keys, n_sources))
        for key in keys:
            np.add.at(sums, key, g)
        return sums.T @ sums

    n_people = int(who.max()) + 1
    clips_part = meat([clip_w, clip_l], n_clips)
    both = meat([who * n_clips + clip_w, who * n_clips + clip_l], n_people * n_clips)
    # Small-sample factors G / (G - 1) of each clustering (CR1).
    middle = (meat([who], n_people) * n_people / max(n_people - 1, 1)
              + (clips_part - both) * n_clips / max(n_clips - 1, 1))
    bread = post.cov  # the centred inverse information (with the weak prior)
    variance = bread @ middle @ bread
    d = np.diag(variance)
    var_diff = np.maximum(d[:, None] + d[None, :] - 2 * variance, 1e-12)
    df = max(1, min(n_people - 1, 2 * clips_per_source - 2))
    t = stats.t.ppf(0.5 + confidence / 2, df)
    m = np.diag(post.cov)
    model = m[:, None] + m[None, :] - 2 * post.cov
    # For deciding when to stop, a steadier variance than each pair's own sandwich: the
    # model's (judgements) plus clips' random effects, tau^2 times how much each source's
    # estimate leans on single clips (sum of squared shares of its clips' showings), with
    # one tau^2 over every pair of sources (moments of the sandwich's excess).
    showings = np.bincount(np.concatenate([clip_w, clip_l]), minlength=n_clips).astype(float)
    source_of = np.arange(n_clips) // clips_per_source
    per_source = np.bincount(source_of, weights=showings, minlength=n_sources)
    lean = np.bincount(source_of, weights=showings ** 2, minlength=n_sources) / np.maximum(per_source, 1) ** 2
    factor = lean[:, None] + lean[None, :]
    upper = np.triu_indices(n_sources, 1)
    tau2 = max(0.0, (var_diff - model)[upper].sum() / factor[upper].sum())
    steady = model + tau2 * factor
    return theta, t * np.sqrt(var_diff), t * np.sqrt(steady)


def crossed_intervals(n_sources, data, pairs, seed, bootstrap=1000, confidence=0.95):
    """Return the study's own intervals of the differences ``pairs`` (``a - b``): the
    pairwise analysis's Bradley-Terry fit with the crossed bootstrap of participants and
    clips (:func:`analysis.pairwise.bradley_terry`, :func:`analysis.crossed.differences`),
    as ``{(a, b): (estimate, low, high)}``."""
    import pandas as pd

    from analysis import crossed
    from analysis.pairwise import bradley_terry
    from analysis.study import AnalysisConfig

    winner, loser, clip_w, clip_l, who = (np.asarray(c) for c in data)
    n = len(winner)
    decided = pd.DataFrame({"winner": winner, "loser": loser})
    rows = pd.DataFrame({"trial_key": np.repeat(np.arange(n), 2), "pcode": np.repeat(who, 2),
                         "stimulus": np.stack([clip_w, clip_l], 1).ravel(),
                         "source": np.stack([winner, loser], 1).ravel(), "action": "walk"})
    names = [f"s{i}" for i in range(n_sources)]
    result = bradley_terry(decided, rows, names, AnalysisConfig(bootstrap=bootstrap, seed=seed,
                                                                confidence=confidence))
    table = crossed.differences(result, list(range(n_sources)), confidence)
    out = {}
    for row in table.itertuples():
        out[(row.a, row.b)] = (row.difference, row.ci_low, row.ci_high)
        out[(row.b, row.a)] = (-row.difference, -row.ci_high, -row.ci_low)
    return {pair: out[pair] for pair in pairs}


def run_study(design, strength, clip_quality, args, seed):
    """Return per target the judgements at stopping and whether the intervals covered."""
    k = len(strength)
    rng = random.Random(seed)
    answers = np.random.default_rng(seed + 10_000)
    clips = {s: list(range(s * args.clips, (s + 1) * args.clips)) for s in range(k)}
    source_of = np.repeat(np.arange(k), args.clips)
    true = truth(strength, args.clip_sd)
    dist = adaptive.balanced(k)
    shown = Counter()
    data = [[], [], [], [], []]
    done = {}
    participant, queue = -1, []
    n = 0
    wanted = len(args.targets) * len(getattr(args, "rules", None) or [args.rule])
    while n < args.budget and len(done) < wanted:
        if not queue:
            participant += 1
            queue = adaptive.plan_pairs(dist, args.trials, clips, shown, rng,
                                        min_showings=args.min_showings)
        left, right = queue.pop(0)
        left_wins = answers.random() < expit(clip_quality[left] - clip_quality[right])
        w, l = (left, right) if left_wins else (right, left)
        for column, value in zip(data, (source_of[w], source_of[l], w, l, participant)):
            column.append(value)
        n += 1
        if n % args.every:
            continue
        theta, half, steady = intervals(k, data, args.clips)
        look = {"sandwich": half, "information": steady, "larger": np.maximum(half, steady)}[args.stop_on]
        if args.interval == "larger":
            half = np.maximum(half, steady)
        order = np.argsort(-theta)
        pairs = {"top_two": [(order[0], order[1])],
                 "order": list(zip(order[:-1], order[1:]))}
        rules = getattr(args, "rules", None) or [args.rule]
        if "app" in rules:
            post = adaptive.posterior(k, data[0], data[1])
            spread = adaptive.spread(post, *data)
        for rule in rules:
            for target, which in pairs.items():
                key = target if rule == rules[0] else f"{target}@{rule}"
                if target not in args.targets or key in done:
                    continue
                limit = args.top_width if target == "top_two" else args.order_width
                if rule == "app":
                    # The app's stopping rule: the steady 95 % interval (study.stop_when).
                    state = adaptive.stop_state(post, {"interval_width": limit}, target, n,
                                                spread, draws=200, seed=n)
                    reached = bool(state["met"])
                else:
                    reached = max(2 * look[a, b] for a, b in which) <= limit
                if not reached:
                    continue
                covered = [abs((theta[a] - theta[b]) - (true[a] - true[b])) <= half[a, b]
                           for a, b in which]
                done[key] = {"n": n, "covered": covered,
                             "width": max(2 * half[a, b] for a, b in which)}
                if args.crossed:
                    own = crossed_intervals(k, data, which, seed + n, args.bootstrap)
                    done[key]["crossed_covered"] = [
                        low <= true[a] - true[b] <= high for (a, b), (_, low, high) in own.items()]
                    done[key]["crossed_width"] = max(high - low for _, low, high in own.values())
        if design != "balanced":
            post = adaptive.posterior(k, data[0], data[1])
            target, batch = design, 0
            if design.endswith("_batch"):  # planned as a batch of the next look's comparisons
                target, batch = design[:-len("_batch")], args.every
            dist = adaptive.distribution(post, target, floor=args.floor,
                                         sharpness=args.sharpness, focus=args.focus,
                                         seed=seed + n, batch=batch)
    for rule in getattr(args, "rules", None) or [args.rule]:
        for target in ("top_two", "order"):
            key = target if rule == (getattr(args, "rules", None) or [args.rule])[0] else f"{target}@{rule}"
            done.setdefault(key, {"n": None, "covered": []})
    return done


def run_sets_study(design, strength, clip_quality, args, seed):
    """Return, for best of ``--sets`` k (one Luce choice per trial among its k sources'
    clips, Plackett-Luce with clip qualities), the judgements until the Plackett-Luce
    posterior's interval of the target (the model's alone: no clip term for sets) is at
    most the width, and whether the intervals there covered the truth (the sources'
    strengths: the estimand of infinitely many clips, up to the clips' spread)."""
    k = len(strength)
    rng = random.Random(seed)
    answers = np.random.default_rng(seed + 10_000)
    clips = {s: list(range(s * args.clips, (s + 1) * args.clips)) for s in range(k)}
    source_of = np.repeat(np.arange(k), args.clips)
    true = strength - strength.mean()
    dist = adaptive.balanced_sets(k, args.sets)
    shown = Counter()
    chosen, among = [], []
    done, queue, n = {}, [], 0
    while n < args.budget and len(done) < len(args.targets):
        if not queue:
            queue = adaptive.plan_sets(dist, args.trials, clips, shown, rng,
                                       min_showings=args.min_showings)
        trial = queue.pop(0)
        utility = clip_quality[list(trial)] + answers.gumbel(size=len(trial))
        chosen.append(source_of[trial[int(np.argmax(utility))]])
        among.append([source_of[c] for c in trial])
        n += 1
        if n % args.every:
            continue
        post = adaptive.choice_posterior(k, chosen, among)
        for target in args.targets:
            limit = args.top_width if target == "top_two" else args.order_width
            state = adaptive.stop_state(post, {"interval_width": limit}, target, n, draws=200, seed=n)
            if target not in done and state["met"]:
                half = 1.959964 * np.sqrt(adaptive.difference_variance(post.cov))
                pairs = [tuple(pair) for pair in state["pairs"]]
                done[target] = {"n": n, "width": state["width"],
                                "covered": [abs(post.mean[a] - post.mean[b] - (true[a] - true[b]))
                                            <= half[a, b] for a, b in pairs]}
        if design != "balanced":
            dist = adaptive.set_distribution(post, args.sets, design, depth=1, floor=args.floor,
                                             sharpness=args.sharpness, focus=args.focus, seed=seed + n)
    for target in ("top_two", "order"):
        done.setdefault(target, {"n": None, "covered": []})
    return done


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--studies", type=int, default=20)
    parser.add_argument("--every", type=int, default=100)
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--clips", type=int, default=20)
    parser.add_argument("--clip-sd", type=float, default=0.3)
    parser.add_argument("--min-showings", type=int, default=2)
    parser.add_argument("--top-width", type=float, default=0.6)
    parser.add_argument("--order-width", type=float, default=0.7)
    parser.add_argument("--budget", type=int, default=20000)
    parser.add_argument("--floor", type=float, default=adaptive.FLOOR)
    parser.add_argument("--sharpness", type=float, default=2.0)
    parser.add_argument("--focus", type=float, default=2.0)
    parser.add_argument("--designs", default="balanced,top_two,order")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--stop-on", choices=("sandwich", "information", "larger"),
                        default="larger")
    parser.add_argument("--interval", choices=("sandwich", "larger"), default="larger",
                        help="the reported interval: the sandwich's, or the larger of it and "
                        "the steady one the stopping rule reads")
    parser.add_argument("--targets", default="top_two,order")
    parser.add_argument("--rule", choices=("reported", "app"), default="reported",
                        help="stop when the reported interval is at most the width (reported), or "
                        "by the app's stopping rule, study.stop_when: {interval_width: W} (app)")
    parser.add_argument("--rules", default="",
                        help="several rules at once, e.g. reported,app: each stops its own copy "
                        "of the same simulated study (the answers do not depend on the rule)")
    parser.add_argument("--crossed", action="store_true",
                        help="also compute the study's own crossed-bootstrap intervals at the "
                        "stop and their coverage")
    parser.add_argument("--bootstrap", type=int, default=1000)
    parser.add_argument("--sets", type=int, default=0,
                        help="best of this many sources per trial instead of pairs (Plackett-Luce; "
                        "the app's rule on the model's interval; no --crossed)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    designs = args.designs.split(",")
    args.targets = args.targets.split(",")
    args.rules = args.rules.split(",") if args.rules else [args.rule]
    results = {d: [] for d in designs}
    started = time.perf_counter()
    for study in range(args.studies):
        seed = args.first_seed + study
        clip_rng = np.random.default_rng(seed)
        quality = np.repeat(STRENGTHS, args.clips) + clip_rng.normal(0, args.clip_sd, len(STRENGTHS) * args.clips)
        for design in designs:
            run = run_sets_study if args.sets else run_study
            results[design].append(run(design, STRENGTHS, quality, args, seed))
    seconds = time.perf_counter() - started
    rows = []
    keys = [(target if rule == args.rules[0] else f"{target}@{rule}", target, rule)
            for rule in args.rules for target in args.targets]
    for key, target, rule in keys:
        base = None
        for design in designs:
            ns = [r[key]["n"] for r in results[design]]
            reached = [x for x in ns if x is not None]
            covered = [c for r in results[design] for c in r[key]["covered"]]
            widths = [r[key]["width"] for r in results[design] if r[key]["n"]]
            all_covered = [all(r[key]["covered"]) for r in results[design] if r[key]["n"]]
            mean = float(np.mean(reached)) if reached else float("nan")
            if design == "balanced":
                base = mean
            crossed_cov = [c for r in results[design] for c in r[key].get("crossed_covered", [])]
            crossed_w = [r[key]["crossed_width"] for r in results[design] if "crossed_width" in r[key]]
            rows.append({
                "crossed_coverage": float(np.mean(crossed_cov)) if crossed_cov else float("nan"),
                "crossed_width": float(np.mean(crossed_w)) if crossed_w else float("nan"),
                "target": target, "rule": rule,
                "design": design if design == "balanced" else f"adaptive {design}",
                "reached": f"{len(reached)}/{len(ns)}",
                "median": float(np.median(reached)) if reached else float("nan"),
                "mean": mean,
                "vs_balanced": mean / base - 1 if base else float("nan"),
                "coverage": float(np.mean(covered)) if covered else float("nan"),
                "all_covered": float(np.mean(all_covered)) if all_covered else float("nan"),
                "intervals": len(covered),
                "width": float(np.mean(widths)) if widths else float("nan"),
            })
    width = {"top_two": args.top_width, "order": args.order_width}
    print(f"{args.studies} studies per design, 8 sources, "
          f"{f'best of {args.sets}' if args.sets else 'pairs'}, {args.clips} clips per source "
          f"(clip SD {args.clip_sd}), {args.trials} trials per participant, looks every "
          f"{args.every} judgements; {seconds:.0f} s")
    extra = " crossed coverage | crossed width |" if args.crossed else ""
    print("| target (width) | stop | design | reached | median judgements | mean | vs balanced | "
          "coverage (intervals) | all covered | width at stop |" + extra)
    print("|---|---|---|---|---|---|---|---|---|---|" + ("---|---|" if args.crossed else ""))
    for row in rows:
        more = (f" {row['crossed_coverage']:.3f} | {row['crossed_width']:.2f} |" if args.crossed else "")
        print(f"| {row['target']} ({width[row['target']]}) | {row['rule']} | {row['design']} | {row['reached']} | "
              f"{row['median']:.0f} | {row['mean']:.0f} | {row['vs_balanced']:+.0%} | "
              f"{row['coverage']:.3f} ({row['intervals']}) | {row['all_covered']:.2f} | "
              f"{row['width']:.2f} |{more}")
    if args.json:
        args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                         "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
