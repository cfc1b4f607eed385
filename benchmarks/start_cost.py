"""What starting a session costs as a study fills: the balanced planning at every start.

``.venv/bin/python benchmarks/start_cost.py --participants 2000`` creates a fresh
PostgreSQL database and the load test's ranking study (12 clips, 3 a trial), then starts
``--participants`` sessions one after another (``ParticipantManager.start``: the study's row
locked, the balance read, the session planned and stored), and prints, for each block of
``--block`` starts, the mean wall-clock time of a start, the process's CPU time, and the SQL
statements it ran. A start holds the study's row for its whole length, so its time bounds how
many people a second can start, whatever the number of workers. ``--code DIR`` measures the
app code of another checkout under the same driver (the previous code, side by side).
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

from benchmarks.server import create_database, drop_database, server_env  # noqa: E402


def drive(participants: int, trials: int, block: int) -> None:
    from django.db import connection

    from benchmarks.loadtest import make_study
    from studyapp.survey.models import Participant

    study = make_study("starts", Path(os.environ["STUDY_VAR_DIR"]) / "media", trials=trials)
    wall = cpu = statements = 0.0

    def count(execute, sql, params, many, context):
        nonlocal statements
        statements += 1
        return execute(sql, params, many, context)

    for i in range(1, participants + 1):
        person = Participant.objects.create(study=study, seed=i, external_key=f"start-{i}")
        w, c = time.perf_counter(), time.process_time()
        with connection.execute_wrapper(count):
            Participant.objects.start(person)
        wall += time.perf_counter() - w
        cpu += time.process_time() - c
        if i % block == 0:
            print(f"starts={i - block + 1}..{i} wall_ms={1000 * wall / block:.2f} "
                  f"cpu_ms={1000 * cpu / block:.2f} statements={statements / block:.1f}",
                  flush=True)
            wall = cpu = statements = 0.0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--participants", type=int, default=2000)
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--block", type=int, default=250, help="Starts per printed line.")
    parser.add_argument("--code", type=Path, default=None,
                        help="Measure the app code of this checkout.")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    code = (args.code or ROOT).resolve()
    if args.inner:
        sys.path.insert(0, str(code))
        import django
        from django.core.management import call_command

        django.setup()
        call_command("migrate", verbosity=0)
        drive(args.participants, args.trials, args.block)
        return 0
    name = f"starts_{os.getpid()}"
    var = Path(tempfile.mkdtemp(prefix="starts-var-"))
    env = server_env(create_database(name), var)
    env.update(PYTHONPATH=str(code), DJANGO_SETTINGS_MODULE="studyapp.settings")
    print(f"code={'this checkout' if code == ROOT else code}", flush=True)
    try:
        run = subprocess.run(
            [sys.executable, __file__, "--inner", "--participants", str(args.participants),
             "--trials", str(args.trials), "--block", str(args.block), "--code", str(code)],
            env=env, cwd=code, check=False)
    finally:
        drop_database(name)
    return run.returncode


if __name__ == "__main__":
    sys.exit(main())
