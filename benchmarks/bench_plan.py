"""Do `plan`'s recommendations reach their stated power? Per study type, in simulation.

    .venv/bin/python benchmarks/bench_plan.py [--types T,...] [--studies 200]
                                              [--plan-studies 50] [--pilots 10]
                                              [--json out.json] [--markdown out.md]

For every study type (``--types``), as ``manage.py plan --type T`` does with its
defaults (effect 0.5, clip SD 0.5, 10 trials, one condition, participants 20/40/80 x
clips 2/4/8, ``--plan-studies`` studies per design, 100 resamples, target power 0.8):

- **assumptions**: :func:`analysis.plan.simulated_power`, :func:`~analysis.plan.recommend`
  and :func:`~analysis.plan.confirm`, as the command runs them, give a design and its
  stated power (the confirming studies'; the grid's estimate of the picked design is
  printed beside it, biased upward by the picking); ``--studies`` fresh studies of that
  design (seeds neither drew) are analysed the same way and their power counted, with
  its Wilson interval.
- **pilot**: ``--pilots`` pilot studies (40 participants, 4 clips per source, fresh seeds)
  each give :func:`~analysis.plan.pilot_power` a difference, a standard error and variance
  shares; the interval width it predicts for every design of the grid is compared with
  the mean width measured there (``--width-studies`` fresh studies per design, the
  recommended one's ``--studies``; the same for every pilot). Reported: the median and the range over pilots of predicted /
  measured width, per design.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis import plan  # noqa: E402
from analysis.simulate import STUDY_TYPES, simulate  # noqa: E402
from analysis.stats import wilson_interval  # noqa: E402
from analysis.study import AnalysisConfig, analyse  # noqa: E402

PARTICIPANTS = (20, 40, 80)
CLIPS = (2, 4, 8)
PILOT = (40, 4)  # participants, clips per source and condition
FRESH_SEED = 1_000_000  # first seed of the checking studies (plan draws seeds 0 + 7919 r)


def fresh(assumptions, participants, clips, studies, bootstrap, first_seed):
    """Return (p, width) of ``studies`` fresh simulated studies of one design."""
    found = []
    for r in range(studies):
        seed = first_seed + r
        table = simulate(assumptions.study_type, {"a": assumptions.effect, "b": 0.0},
                         participants=participants, trials=assumptions.trials,
                         actions=("condition_1",), clips_per_source=clips,
                         clip_sd=assumptions.clip_sd, noise=assumptions.noise,
                         clips_per_trial=assumptions.clips_per_trial, seed=seed)
        found.append(plan._difference(analyse(table, AnalysisConfig(bootstrap=bootstrap, seed=seed))))
    return np.array([f["p"] for f in found]), np.array([f["width"] for f in found])


def check_type(study_type, args) -> dict:
    assumptions = plan.Assumptions(study_type, effect=args.effect, clip_sd=args.clip_sd,
                                   trials=args.trials)
    started = time.perf_counter()
    stated = plan.simulated_power(assumptions, PARTICIPANTS, CLIPS, studies=args.plan_studies,
                                  bootstrap=args.bootstrap)
    best = plan.confirm(assumptions, plan.recommend(stated, target=args.target),
                        args.plan_studies, args.bootstrap, target=args.target)
    design = (int(best["participants"]), int(best["clips"]))
    # Every design's fresh studies: the recommendation's power, and the widths pilots predict.
    measured = {}
    for n_participants in PARTICIPANTS:
        for n_clips in CLIPS:
            d = (n_participants, n_clips)
            measured[d] = fresh(assumptions, n_participants, n_clips,
                                args.studies if d == design else args.width_studies,
                                args.bootstrap, FRESH_SEED + 10_000 * (n_participants + n_clips))
    p, _ = measured[design]
    hits = int((p < 0.05).sum())
    low, high = wilson_interval(hits, len(p))
    ratios = {d: [] for d in measured}
    for k in range(args.pilots):
        seed = 2 * FRESH_SEED + k
        table = simulate(study_type, {"a": args.effect, "b": 0.0}, participants=PILOT[0],
                         trials=args.trials, actions=("condition_1",), clips_per_source=PILOT[1],
                         clip_sd=args.clip_sd, clips_per_trial=assumptions.clips_per_trial,
                         seed=seed)
        components = plan.pilot_components(
            analyse(table, AnalysisConfig(bootstrap=args.bootstrap, seed=seed)), "a", "b")
        predicted = plan.pilot_power(components, PARTICIPANTS, CLIPS)
        for row in predicted.itertuples():
            d = (int(row.participants), int(row.clips))
            ratios[d].append(row.width / measured[d][1].mean())
    return {
        "study_type": study_type, "effect": args.effect, "clip_sd": args.clip_sd,
        "recommended": {"participants": design[0], "clips": design[1],
                        "reached": bool(best["reached"]), "stated": float(best["power"]),
                        "grid": float(best["grid_power"]),
                        "stated_low": float(best["power_low"]),
                        "stated_high": float(best["power_high"])},
        "measured": {"power": hits / len(p), "low": float(low), "high": float(high),
                     "studies": len(p)},
        "pilot_width_ratio": {f"{d[0]}x{d[1]}": [float(np.median(r)), float(np.min(r)),
                                                 float(np.max(r))] for d, r in ratios.items()},
        "seconds": round(time.perf_counter() - started, 1),
    }


def markdown(results) -> str:
    lines = ["| type | recommended (participants x clips) | grid's estimate | stated power (plan, "
             "confirmed) | measured power (fresh studies) | pilot width / measured: median "
             "(range) over all designs |",
             "|---|---|---|---|---|---|"]
    for r in results:
        rec, got = r["recommended"], r["measured"]
        mark = "" if rec["reached"] else " (target not reached)"
        medians = [v[0] for v in r["pilot_width_ratio"].values()]
        lows = [v[1] for v in r["pilot_width_ratio"].values()]
        highs = [v[2] for v in r["pilot_width_ratio"].values()]
        lines.append(
            f"| `{r['study_type']}` | {rec['participants']} x {rec['clips']}{mark} | "
            f"{rec['grid']:.2f} | {rec['stated']:.2f} [{rec['stated_low']:.2f}, {rec['stated_high']:.2f}] | "
            f"{got['power']:.3f} [{got['low']:.3f}, {got['high']:.3f}] ({got['studies']}) | "
            f"{np.median(medians):.2f} ({min(lows):.2f}-{max(highs):.2f}) |")
    return "\n".join(lines) + "\n"


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--types", type=lambda s: s.split(","), default=list(STUDY_TYPES))
    parser.add_argument("--studies", type=int, default=200,
                        help="fresh studies per design to measure power and width")
    parser.add_argument("--width-studies", type=int, default=40,
                        help="fresh studies per other design to measure the width pilots predict")
    parser.add_argument("--plan-studies", type=int, default=50,
                        help="studies per design the plan simulates (plan's default)")
    parser.add_argument("--pilots", type=int, default=10)
    parser.add_argument("--bootstrap", type=int, default=100)
    parser.add_argument("--effect", type=float, default=0.5)
    parser.add_argument("--clip-sd", type=float, default=0.5)
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--target", type=float, default=0.8)
    parser.add_argument("--json", help="write the results here as they come")
    parser.add_argument("--markdown", help="write the table here at the end")
    return parser.parse_args(argv)


def main(argv=None):
    warnings.simplefilter("ignore")
    args = parse(argv)
    results = []
    for study_type in args.types:
        results.append(check_type(study_type, args))
        r = results[-1]
        print(f"{study_type:17s} recommended {r['recommended']['participants']} x "
              f"{r['recommended']['clips']}: grid {r['recommended']['grid']:.2f}, stated "
              f"{r['recommended']['stated']:.2f}, measured "
              f"{r['measured']['power']:.3f} ({r['seconds']:.0f} s)", flush=True)
        if args.json:
            Path(args.json).write_text(json.dumps(results, indent=1))
    table = markdown(results)
    if args.markdown:
        Path(args.markdown).write_text(table)
    print(table)


if __name__ == "__main__":
    main()
