"""Two app nodes behind a real HAProxy, one PostgreSQL, one Redis, one node killed mid-study.

``benchmarks/nodes.py`` with a few dozen bots (the benchmark runs 500): nothing lost or
stored twice, balanced assignment exact across the nodes, the rate limit counted once for
both. Needs PostgreSQL (several nodes cannot share an SQLite file: this runs in the
suite's PostgreSQL pass), Redis and HAProxy; ``STUDY_REQUIRE_SERVICES=1`` (CI) turns the
skip into a failure.
"""

from pathlib import Path

import pytest
from django.db import connection

from benchmarks import nodes
from benchmarks.server import HAPROXY, NGINX
from tests.studyapp.conftest import require_service
from tests.studyapp.test_faults import database_url
from tests.studyapp.test_tasks import redis_up

pytestmark = [pytest.mark.slow, pytest.mark.django_db(transaction=True)]


@pytest.mark.parametrize("behind_nginx", [False, True], ids=["gunicorn", "nginx"])
def test_two_nodes_one_killed_lose_nothing_store_nothing_twice_and_share_limits(
        tmp_path, media_root, settings, behind_nginx):
    if connection.vendor == "sqlite":
        pytest.skip("several nodes share PostgreSQL, not an SQLite file "
                    "(DATABASE_URL=postgres://...: the suite's PostgreSQL pass runs this)")
    require_service(redis_up(), "Redis on 127.0.0.1:6379")
    require_service(Path(HAPROXY).exists(), f"HAProxy ({HAPROXY})")
    if behind_nginx:  # each node as `make serve` runs it; the kill takes the node whole
        require_service(Path(NGINX).exists(), f"nginx ({NGINX})")
    result = nodes.run(database_url(), tmp_path / "var", participants=20, trials=4,
                       workers=2, kill_at=0.4, time_limit=120, behind_nginx=behind_nginx)
    assert 0 < result["killed_at"] < 20 * 4  # killed mid-study
    assert result["stored_participants"] == result["completed"] == 20
    assert result["participants_twice"] == 0
    assert result["answered"] == result["trials"] == 20 * 4
    assert result["items"] == result["trials"] * 3
    assert (result["missing"], result["duplicates"], result["bad_rankings"]) == (0, 0, 0)
    assert result["assigned_spread"] <= 1  # every trial shows every source: exact balance
    # a per-study limit of 3 x 20 consents (bots that come back consent again)
    assert (result["limited_passed"], result["limited_refused"]) == (60, 20)
    assert all(n > 0 for n in result["served_by"].values()) and len(result["served_by"]) == 2
    assert result["ok"], result


def test_start_cost_prints_a_consent_and_a_start_per_block():
    import subprocess
    import sys

    if connection.vendor == "sqlite":
        pytest.skip("the benchmark makes a PostgreSQL database of its own (the suite's "
                    "PostgreSQL pass runs this)")
    script = Path(__file__).resolve().parents[2] / "benchmarks" / "start_cost.py"
    run = subprocess.run([sys.executable, str(script), "--participants", "4", "--block", "2"],
                         capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = [line for line in run.stdout.splitlines() if line.startswith("people=")]
    assert [line.split()[0] for line in lines] == ["people=1..2", "people=3..4"]
    assert all("enroll: wall_ms=" in line and "start: wall_ms=" in line for line in lines)
