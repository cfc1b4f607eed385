"""Coverage, false positives and power of the intervals of source differences, per study type.

    .venv/bin/python benchmarks/bench_coverage.py [--studies 200] [--types ranking,...]
                                                  [--json out.json] [--markdown out.md]
                                                  [--methods crossed,participants] [--first-seed 0]
                                                  [--clip-sds 0,0.5,1.5] [--clips 2,8]

Every cell simulates ``--studies`` studies (``analysis.simulate``: two sources ``a`` and
``b``, ``--participants`` x ``--trials`` main trials, ``--actions`` conditions) and
analyses each through ``analysis.study.analyse`` twice: with clips random (the default,
:mod:`analysis.crossed`) and with clips fixed (intervals over participants only, as
before; ``--methods`` picks one). Runs with different ``--first-seed`` draw different
studies and can be pooled. Cells: every study type x clip SD {0, 0.5, 1.5} (logit
scale) x clips per source and condition {2, 8} x equal strengths (a = b) or unequal
(a - b = ``--effect``); ``--clip-sds`` and ``--clips`` run some of them only.

Measured per cell and method, on the difference a - b of the type's headline statistic:

- coverage: the share of 95 % intervals holding the true difference (0 at equal
  strengths; at unequal strengths the mean difference of ``--truth-repeats`` studies of
  ``TRUTH_CLIPS`` clips per source and condition and ``TRUTH_PARTICIPANTS`` participants,
  no bootstrap), with its Wilson 95 % interval over the cell's studies;
- false positives (equal strengths): the share of p < 0.05;
- power (unequal strengths): the share of p < 0.05;
- the mean width of the interval.

Targets: coverage >= 0.93 and false positives <= 0.07 in every cell.
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

from analysis.simulate import STUDY_TYPES, simulate  # noqa: E402
from analysis.stats import wilson_interval  # noqa: E402
from analysis.study import AnalysisConfig, analyse  # noqa: E402

CLIP_SDS = (0.0, 0.5, 1.5)
CLIPS = (2, 8)
TRUTH_CLIPS = 200
TRUTH_PARTICIPANTS = 400


def difference(result) -> dict:
    """Return the a - b row of a result's differences table (sign flipped if b - a)."""
    table = result.analysis.tests["differences"]
    row = table.loc[((table["a"] == "a") & (table["b"] == "b"))
                    | ((table["a"] == "b") & (table["b"] == "a"))].iloc[0]
    sign = 1.0 if row["a"] == "a" else -1.0
    low, high = sorted((sign * row["ci_low"], sign * row["ci_high"]))
    return {"difference": sign * row["difference"], "low": low, "high": high, "p": row["p"]}


def study(study_type, effect, clip_sd, clips, args, seed, participants=None, bootstrap=None,
          random_clips=True):
    table = simulate(study_type, {"a": effect, "b": 0.0}, participants=participants or args.participants,
                     trials=args.trials, actions=tuple(f"c{i}" for i in range(args.actions)),
                     clips_per_source=clips, clip_sd=clip_sd, clips_per_trial=2, seed=seed)
    config = AnalysisConfig(bootstrap=args.bootstrap if bootstrap is None else bootstrap,
                            seed=seed, random_clips=random_clips)
    return difference(analyse(table, config))


def truth(study_type, effect, clip_sd, args) -> float:
    """Return the difference a - b of one very large study (its estimate is the target)."""
    if effect == 0:
        return 0.0
    values = [study(study_type, effect, clip_sd, TRUTH_CLIPS, args, 10_000 + r,
                    participants=TRUTH_PARTICIPANTS, bootstrap=0)["difference"]
              for r in range(args.truth_repeats)]
    return float(np.mean(values))


def cell(study_type, effect, clip_sd, clips, target, args) -> dict:
    out = {"study_type": study_type, "clip_sd": clip_sd, "clips": clips, "effect": effect,
           "truth": target, "studies": args.studies}
    for label, random_clips in (("crossed", True), ("participants", False)):
        if label not in getattr(args, "methods", ("crossed", "participants")):
            continue
        rows = [study(study_type, effect, clip_sd, clips, args, seed, random_clips=random_clips)
                for seed in range(args.first_seed, args.first_seed + args.studies)]
        covered = [r["low"] <= target <= r["high"] for r in rows]
        rejected = [r["p"] < 0.05 for r in rows]
        out[label] = {"coverage": float(np.mean(covered)), "rejected": float(np.mean(rejected)),
                      "width": float(np.mean([r["high"] - r["low"] for r in rows]))}
    return out


def run(args) -> list[dict]:
    results = []
    for study_type in args.types:
        for clip_sd in args.clip_sds:
            targets = {0.0: 0.0, args.effect: truth(study_type, args.effect, clip_sd, args)}
            for clips in args.clips:
                for effect, target in targets.items():
                    started = time.perf_counter()
                    results.append(cell(study_type, effect, clip_sd, clips, target, args))
                    r = results[-1]
                    measured = " | ".join(f"{label} cover {r[label]['coverage']:.3f} reject "
                                          f"{r[label]['rejected']:.3f}" for label in args.methods)
                    print(f"{study_type:17s} sd {clip_sd:3.1f} m {clips} effect {effect:3.1f}: "
                          f"{measured} ({time.perf_counter() - started:.0f} s)", flush=True)
                    if args.json:
                        Path(args.json).write_text(json.dumps(results, indent=1))
    return results


def markdown(results) -> str:
    """Return the results as a table: one row per cell."""
    lines = ["| type | clip SD | clips | a - b | studies | crossed coverage | crossed p < .05 "
             "| crossed width | participants-only coverage | participants-only p < .05 "
             "| participants-only width |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    missing = {"coverage": float("nan"), "rejected": float("nan"), "width": float("nan")}
    for r in results:
        c, p = r.get("crossed", missing), r.get("participants", missing)
        effect = "0" if r["effect"] == 0 else f"{r['effect']:g} (true {r['truth']:.3g})"
        studies = (f"{r['studies']} ({r['participants_studies']} participants only)"
                   if "participants_studies" in r else f"{r['studies']}")
        covered = c["coverage"]
        if covered == covered:  # with its Wilson interval over the cell's studies
            low, high = wilson_interval(round(covered * r["studies"]), r["studies"])
            covered = f"{covered:.3f} [{low:.3f}, {high:.3f}]"
        else:
            covered = "nan"
        lines.append(f"| `{r['study_type']}` | {r['clip_sd']:g} | {r['clips']} | {effect} | "
                     f"{studies} | "
                     f"{covered} | {c['rejected']:.3f} | {c['width']:.3g} | "
                     f"{p['coverage']:.3f} | {p['rejected']:.3f} | {p['width']:.3g} |")
    return "\n".join(lines) + "\n"


def pooled(paths) -> list[dict]:
    """Return the cells of the JSON results in ``paths``, the runs of one cell and method
    pooled (their rates weighed by their studies), in the order first seen; a cell's
    ``studies`` are its crossed method's (or the other's when it has none)."""
    cells, counts = {}, {}
    for path in paths:
        for r in json.loads(Path(path).read_text()):
            key = (r["study_type"], r["clip_sd"], r["clips"], r["effect"])
            cell = cells.setdefault(key, {k: v for k, v in r.items()
                                          if k not in ("crossed", "participants")})
            for label in ("crossed", "participants"):
                if label not in r:
                    continue
                before = counts.get((key, label), 0)
                total = before + r["studies"]
                old = cell.get(label, {k: 0.0 for k in r[label]})
                cell[label] = {k: (old[k] * before + r[label][k] * r["studies"]) / total
                               for k in r[label]}
                counts[(key, label)] = total
            cell["studies"] = counts.get((key, "crossed"), counts.get((key, "participants"), 0))
            if "crossed" in cell and "participants" in cell and \
                    counts[(key, "crossed")] != counts[(key, "participants")]:
                cell["participants_studies"] = counts[(key, "participants")]
    return list(cells.values())


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--studies", type=int, default=200, help="simulated studies per cell")
    parser.add_argument("--types", type=lambda s: s.split(","), default=list(STUDY_TYPES))
    parser.add_argument("--clip-sds", type=lambda s: [float(v) for v in s.split(",")],
                        default=list(CLIP_SDS), help="clip SDs (logit scale) to run")
    parser.add_argument("--clips", type=lambda s: [int(v) for v in s.split(",")],
                        default=list(CLIPS), help="clips per source and condition to run")
    parser.add_argument("--participants", type=int, default=40)
    parser.add_argument("--trials", type=int, default=8)
    parser.add_argument("--actions", type=int, default=2)
    parser.add_argument("--effect", type=float, default=0.8,
                        help="a's strength above b's at unequal strengths (logit scale)")
    parser.add_argument("--bootstrap", type=int, default=200, help="resamples per scheme")
    parser.add_argument("--truth-repeats", type=int, default=20,
                        help="large studies whose mean difference is the truth at unequal strengths")
    parser.add_argument("--first-seed", type=int, default=0,
                        help="seed of the first study (runs of different seeds can be pooled)")
    parser.add_argument("--methods", type=lambda s: tuple(s.split(",")),
                        default=("crossed", "participants"),
                        help="crossed (clips random), participants (clips fixed), or both")
    parser.add_argument("--json", help="write the results here as they come")
    parser.add_argument("--from-json", nargs="+", help="print the table of these results "
                        "(runs pooled cell by cell when they have different seeds) and exit")
    parser.add_argument("--markdown", help="write the table here at the end")
    return parser.parse_args(argv)


def main(argv=None):
    warnings.simplefilter("ignore")
    args = parse(argv)
    results = pooled(args.from_json) if args.from_json else run(args)
    table = markdown(results)
    if args.markdown:
        Path(args.markdown).write_text(table)
    print(table)


if __name__ == "__main__":
    main()
