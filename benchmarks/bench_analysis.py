"""Time the analysis of a million simulated judgements; report wall time and peak memory.

    .venv/bin/python benchmarks/bench_analysis.py [--judgements 1000000] [--sources 6] [--report]
                                                  [--study-type KEY]

Every study type the analysis can simulate is timed in turn, or the one ``--study-type``
names. A child process simulates the study (6 sources, 8 actions, 20 trials per
participant, 1,000 bootstrap resamples as the command's default) and writes it as
Parquet, so this process's peak RSS covers reading the table and analysing it, not the
simulation. ``--report`` also times writing report.html, tables and figures.
"""

import argparse
import multiprocessing
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.report import write_report  # noqa: E402
from analysis.simulate import simulate, simulated_types  # noqa: E402
from analysis.study import AnalysisConfig, analyse  # noqa: E402
from analysis.tables import read_responses, write_responses  # noqa: E402

ACTIONS = ("walk", "eat", "jump", "sit", "run", "wave", "kick", "throw")
TRIALS = 20


def write_study(path, study_type, judgements, sources):
    strengths = {f"method_{i}": i / 2 for i in range(sources - 1)}
    strengths["real"] = sources / 2
    # Rows per trial, as the type's simulated trials show them.
    per_trial = len(simulate(study_type, strengths, participants=1, trials=1, actions=ACTIONS))
    participants = max(1, round(judgements / (per_trial * TRIALS)))
    table = simulate(study_type, strengths, participants=participants, trials=TRIALS, actions=ACTIONS,
                     clips_per_source=20, seed=0)
    write_responses(table, path)


def cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: kilobytes


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--judgements", type=int, default=1_000_000)
    parser.add_argument("--sources", type=int, default=6)
    parser.add_argument("--study-type", choices=simulated_types(),
                        help="Time this type only (default: every type in turn).")
    parser.add_argument("--bootstrap", type=int, default=AnalysisConfig.bootstrap)
    parser.add_argument("--report", action="store_true", help="Also time writing the report.")
    args = parser.parse_args()
    for study_type in [args.study_type] if args.study_type else simulated_types():
        run(args, study_type)


def run(args, study_type):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "responses.parquet"
        start = time.perf_counter()
        child = multiprocessing.get_context("spawn").Process(
            target=write_study, args=(path, study_type, args.judgements, args.sources))
        child.start()
        child.join()
        print(f"simulate and write (child process, not timed below): {time.perf_counter() - start:.1f} s")

        start = time.perf_counter()
        table = read_responses(path)
        read = time.perf_counter() - start
        before = peak_mb()
        start, cpu = time.perf_counter(), cpu_seconds()
        result = analyse(table, AnalysisConfig(bootstrap=args.bootstrap))
        core, cpu = time.perf_counter() - start, cpu_seconds() - cpu
        print(f"{study_type}: {len(table):,} judgements, {result.counts['participants']:,} participants, "
              f"{args.sources} sources, {result.counts['actions']} actions, {args.bootstrap} bootstrap resamples")
        print(f"  read Parquet        {read:6.2f} s")
        print(f"  analyse             {core:6.2f} s   ({cpu:.2f} CPU s)   peak RSS {peak_mb():,.0f} MB "
              f"(after reading: {before:,.0f} MB)")
        if args.report:
            start = time.perf_counter()
            written = write_report(result, Path(folder) / "report")
            print(f"  write report        {time.perf_counter() - start:6.2f} s   {len(written)} files, "
                  f"peak RSS {peak_mb():,.0f} MB")
        print("  order:", ", ".join(result.summary()["order"]))


if __name__ == "__main__":
    main()
