"""What entering and starting cost as a study fills: the work done with the study's row locked.

``.venv/bin/python benchmarks/start_cost.py --participants 2000`` creates a fresh
PostgreSQL database and the load test's ranking study (12 clips, 3 a trial) as a Prolific
study with as many places as participants (its ``SESSION_ID`` unique, the places counted at
every consent), then enrols and starts ``--participants`` people one after another
(``ParticipantManager.enroll``: the consent; ``ParticipantManager.start``: the balance read,
the session planned and stored), and prints, for each block of ``--block`` people, the mean
wall-clock time of each, the process's CPU time and the SQL statements they ran. Both hold
the study's row for their whole length, so their time bounds how many people a second can
enter, whatever the number of workers. ``--code DIR`` measures the app code of another
checkout under the same driver (the previous code, side by side).
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.server import (  # noqa: E402
    create_database, drop_database, server_env, setup_django)


def drive(participants: int, trials: int, block: int, time_limit: int | None) -> None:
    from django.db import connection

    from benchmarks.loadtest import PROLIFIC_CROWD, make_study
    from studyapp.survey.models import Participant

    study = make_study("starts", Path(os.environ["STUDY_VAR_DIR"]) / "media", trials=trials,
                       crowd={**PROLIFIC_CROWD, **({"time_limit_minutes": time_limit}
                                                   if time_limit else {})})
    study.max_participants = participants
    study.save()
    spent = {step: [0.0, 0.0, 0] for step in ("enroll", "start")}
    statements = 0

    def count(execute, sql, params, many, context):
        nonlocal statements
        statements += 1
        return execute(sql, params, many, context)

    def timed(step, call):
        nonlocal statements
        statements = 0
        w, c = time.perf_counter(), time.process_time()
        with connection.execute_wrapper(count):
            result = call()
        figures = spent[step]
        figures[0] += time.perf_counter() - w
        figures[1] += time.process_time() - c
        figures[2] += statements
        return result

    for i in range(1, participants + 1):
        ids = {"PROLIFIC_PID": f"{i:024x}", "STUDY_ID": "5" * 24, "SESSION_ID": f"{i:024d}"}
        key = ids["PROLIFIC_PID"]
        person = timed("enroll", lambda: Participant.objects.enroll(study, ids, key))
        timed("start", lambda: Participant.objects.start(person))
        if i % block == 0:
            print(f"people={i - block + 1}..{i} " + " ".join(
                f"{step}: wall_ms={1000 * wall / block:.2f} cpu_ms={1000 * cpu / block:.2f} "
                f"statements={n / block:.1f}" for step, (wall, cpu, n) in spent.items()),
                flush=True)
            spent = {step: [0.0, 0.0, 0] for step in spent}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--participants", type=int, default=2000)
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--block", type=int, default=250, help="People per printed line.")
    parser.add_argument("--time-limit", type=int, default=None,
                        help="The study's time_limit_minutes (as `prolific create` stores "
                             "it); without it, Prolific's default from the study's minutes.")
    parser.add_argument("--code", type=Path, default=None,
                        help="Measure the app code of this checkout.")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    code = (args.code or ROOT).resolve()
    if args.inner:
        setup_django(code)
        drive(args.participants, args.trials, args.block, args.time_limit)
        return 0
    name = f"starts_{os.getpid()}"
    var = Path(tempfile.mkdtemp(prefix="starts-var-"))
    env = server_env(create_database(name), var)
    env.update(PYTHONPATH=str(code), DJANGO_SETTINGS_MODULE="studyapp.settings")
    print(f"code={'this checkout' if code == ROOT else code}", flush=True)
    try:
        run = subprocess.run(
            [sys.executable, __file__, "--inner", "--participants", str(args.participants),
             "--trials", str(args.trials), "--block", str(args.block), "--code", str(code),
             *(["--time-limit", str(args.time_limit)] if args.time_limit else [])],
            env=env, cwd=code, check=False)
    finally:
        drop_database(name)
    return run.returncode


if __name__ == "__main__":
    sys.exit(main())
