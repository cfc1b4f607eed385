"""Judgements an adaptive pairwise design needs against a balanced one, side by side.

    .venv/bin/python benchmarks/bench_adaptive.py [--studies 20] [--every 100]
        [--top-width 0.6] [--order-width 0.7] [--budget 20000] [--targets top_two,order]
        [--designs balanced,top_two,order,order_batch] [--interval larger|sandwich]
        [--stop-on larger|information|sandwich] [--rules reported,app] [--crossed
        [--bootstrap 1000]] [--sets 4 [--ranking]] [--json out.json]

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

``--sets k`` simulates sets of sources instead: each trial shows ``k`` clips of ``k``
sources (:func:`analysis.adaptive.plan_sets`), answered by a pick of the best (a
Plackett-Luce first choice of the clips' qualities) or with ``--ranking`` by a full
ranking (``k - 1`` choices); the adaptive designs draw sets
(:func:`analysis.adaptive.set_distribution`). The rule is the app's, on the
Plackett-Luce posterior's steady interval (:func:`analysis.adaptive.choice_spread`:
clips counted as random); the reported interval is the larger of it and the sandwich,
and the truth the Plackett-Luce worths of infinitely many answers and clips, balanced
(:func:`set_truth`). ``--crossed`` there runs the best-of-k or ranking analysis's own
crossed bootstrap at the stop (:func:`set_crossed_intervals`).
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


def set_truth(strength, clip_sd, size, depth, draws=20_000, seed=0):
    """Return the centred Plackett-Luce worths of infinitely many answers on every set of
    ``size`` sources alike (``depth`` choices each: 1 best of k, ``size - 1`` a ranking)
    with infinitely many clips per source: the estimand of every design of sets. Each
    order's chance is averaged over ``draws`` draws of the set's clip qualities (exact
    given the clips), and the choices it makes are fitted without a prior."""
    import itertools

    sets = adaptive.all_sets(len(strength), size)
    rng = np.random.default_rng(seed)
    quality = strength[sets][:, None, :] + rng.normal(0, clip_sd, (len(sets), draws, size))
    e = np.exp(quality - quality.max(axis=2, keepdims=True))
    chosen, among, weight = [], [], []
    for order in itertools.permutations(range(size)):
        chance = np.ones(e.shape[:2])
        for place in range(depth):
            chance *= e[..., order[place]] / e[..., list(order[place:])].sum(axis=2)
        chance = chance.mean(axis=1)
        for members, p in zip(sets, chance):
            for place in range(depth):
                chosen.append(members[order[place]])
                among.append(members[list(order[place:])])
                weight.append(p * 1e6)
    return adaptive.choice_posterior(len(strength), chosen, among, weight, prior_sd=1e3).mean


def set_crossed_intervals(n_sources, trials, pairs, seed, bootstrap=1000, confidence=0.95,
                          ranking=False):
    """Return the study's own intervals of the differences ``pairs`` (``a - b``) of sets:
    the best-of-k analysis's top-1 worths (:func:`analysis.best_of_k.top1_worth`) or the
    ranking analysis's Plackett-Luce worths (:func:`analysis.ranking.plackett_luce`), each
    with the crossed bootstrap of participants and clips; ``trials`` holds one ``(clips
    best first, their sources, participant)`` per trial."""
    import pandas as pd

    from analysis import crossed
    from analysis.study import AnalysisConfig

    config = AnalysisConfig(bootstrap=bootstrap, seed=seed, confidence=confidence)
    rows = pd.DataFrame([{"trial_key": t, "pcode": who, "stimulus": clip, "source": source,
                          "rank": place + 1, "action": "walk"}
                         for t, (clips, sources, who) in enumerate(trials)
                         for place, (clip, source) in enumerate(zip(clips, sources))])
    names = list(range(n_sources))
    if ranking:
        from analysis.ranking import plackett_luce

        result = plackett_luce(rows, names, config)
    else:
        from analysis.best_of_k import top1_worth

        shown = np.zeros((len(trials), n_sources), dtype=np.int64)
        np.add.at(shown, (rows["trial_key"].to_numpy(), rows["source"].to_numpy()), 1)
        chosen = np.array([sources[0] for _, sources, _ in trials])
        result = top1_worth(shown, chosen, rows, config)
    table = crossed.differences(result, names, confidence)
    out = {}
    for row in table.itertuples():
        out[(row.a, row.b)] = (row.difference, row.ci_low, row.ci_high)
        out[(row.b, row.a)] = (-row.difference, -row.ci_high, -row.ci_low)
    return {pair: out[pair] for pair in pairs}


def run_sets_study(design, strength, clip_quality, args, seed):
    """Return, for best of ``--sets`` k (one Luce choice per trial among its k sources'
    clips) or with ``--ranking`` a ranking of them (``k - 1`` choices; Plackett-Luce with
    the clips' qualities), the judgements (trials) until the app's stopping rule is met on
    the Plackett-Luce posterior's steady interval (clips counted as random:
    :func:`analysis.adaptive.choice_spread`), and whether the intervals there covered the
    truth (:func:`set_truth`)."""
    k = len(strength)
    depth = args.sets - 1 if args.ranking else 1
    rng = random.Random(seed)
    answers = np.random.default_rng(seed + 10_000)
    clips = {s: list(range(s * args.clips, (s + 1) * args.clips)) for s in range(k)}
    source_of = np.repeat(np.arange(k), args.clips)
    true = args.set_truth
    dist = adaptive.balanced_sets(k, args.sets)
    shown = Counter()
    chosen, among, among_clips, who, trials = [], [], [], [], []
    done, queue, n, participant = {}, [], 0, -1
    while n < args.budget and len(done) < len(args.targets):
        if not queue:
            participant += 1
            queue = adaptive.plan_sets(dist, args.trials, clips, shown, rng,
                                       min_showings=args.min_showings)
        trial = np.array(queue.pop(0))
        order = trial[np.argsort(-(clip_quality[trial] + answers.gumbel(size=len(trial))))]
        for place in range(depth):
            chosen.append(source_of[order[place]])
            among.append(source_of[order[place:]])
            among_clips.append(order[place:])
            who.append(participant)
        trials.append((order, source_of[order], participant))
        n += 1
        if n % args.every:
            continue
        post = adaptive.choice_posterior(k, chosen, among)
        spread = adaptive.choice_spread(post, chosen, among, among_clips, who)
        level = stats.t.ppf(0.975, spread.df)
        reported = level * np.sqrt(np.maximum(spread.sandwich, spread.steady))
        steady = level * np.sqrt(spread.steady)
        for target in args.targets:
            limit = args.top_width if target == "top_two" else args.order_width
            if target in done:
                continue
            state = adaptive.stop_state(post, {"interval_width": limit}, target, n, spread,
                                        draws=200, seed=n)
            if not state["met"]:
                continue
            pairs = [tuple(pair) for pair in state["pairs"]]
            error = {(a, b): abs(post.mean[a] - post.mean[b] - (true[a] - true[b])) for a, b in pairs}
            done[target] = {"n": n, "width": max(2 * reported[a, b] for a, b in pairs),
                            "rule_width": state["width"],
                            "covered": [error[a, b] <= reported[a, b] for a, b in pairs],
                            "steady_covered": [error[a, b] <= steady[a, b] for a, b in pairs]}
            if args.crossed:
                own = set_crossed_intervals(k, trials, pairs, seed + n, args.bootstrap,
                                            ranking=args.ranking)
                done[target]["crossed_covered"] = [
                    low <= true[a] - true[b] <= high for (a, b), (_, low, high) in own.items()]
                done[target]["crossed_width"] = max(high - low for _, low, high in own.values())
        if design != "balanced":
            dist = adaptive.set_distribution(post, args.sets, design,
                                             depth=None if args.ranking else 1, floor=args.floor,
                                             sharpness=args.sharpness, focus=args.focus, seed=seed + n)
    for target in ("top_two", "order"):
        done.setdefault(target, {"n": None, "covered": [], "steady_covered": []})
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
                        "the app's rule on the steady interval, clips counted as random)")
    parser.add_argument("--ranking", action="store_true",
                        help="with --sets: each trial a full ranking of its clips instead of a pick")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    designs = args.designs.split(",")
    args.targets = args.targets.split(",")
    args.rules = args.rules.split(",") if args.rules else [args.rule]
    results = {d: [] for d in designs}
    started = time.perf_counter()
    if args.sets:
        args.set_truth = set_truth(STRENGTHS, args.clip_sd, args.sets,
                                   args.sets - 1 if args.ranking else 1)
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
            steady_cov = [c for r in results[design] for c in r[key].get("steady_covered", [])]
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
                "steady_coverage": float(np.mean(steady_cov)) if steady_cov else float("nan"),
                "all_covered": float(np.mean(all_covered)) if all_covered else float("nan"),
                "intervals": len(covered),
                "width": float(np.mean(widths)) if widths else float("nan"),
            })
    width = {"top_two": args.top_width, "order": args.order_width}
    trial = "pairs"
    if args.sets:
        trial = f"rankings of {args.sets}" if args.ranking else f"best of {args.sets}"
    print(f"{args.studies} studies per design, 8 sources, {trial}, {args.clips} clips per source "
          f"(clip SD {args.clip_sd}), {args.trials} trials per participant, looks every "
          f"{args.every} judgements; {seconds:.0f} s")
    extra = (" steady coverage |" if args.sets else "") + (
        " crossed coverage | crossed width |" if args.crossed else "")
    print("| target (width) | stop | design | reached | median judgements | mean | vs balanced | "
          "coverage (intervals) | all covered | width at stop |" + extra)
    print("|---|---|---|---|---|---|---|---|---|---|" + ("---|" if args.sets else "")
          + ("---|---|" if args.crossed else ""))
    for row in rows:
        more = ((f" {row['steady_coverage']:.3f} |" if args.sets else "")
                + (f" {row['crossed_coverage']:.3f} | {row['crossed_width']:.2f} |" if args.crossed else ""))
        print(f"| {row['target']} ({width[row['target']]}) | {row['rule']} | {row['design']} | {row['reached']} | "
              f"{row['median']:.0f} | {row['mean']:.0f} | {row['vs_balanced']:+.0%} | "
              f"{row['coverage']:.3f} ({row['intervals']}) | {row['all_covered']:.2f} | "
              f"{row['width']:.2f} |{more}")
    if args.json:
        args.json.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                         "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
