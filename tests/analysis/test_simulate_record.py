"""``simulate`` writes the same table for the same seed as it did before its per-type
parts moved into the types' analysis modules (hashes recorded then, in a data file)."""

import hashlib
import json
from pathlib import Path

import pytest

from analysis.registry import list_analyses
from analysis.simulate import simulate

RECORD = Path(__file__).parent / "data" / "simulate_hashes.json"
# Every option that changes a table, on a small study.
SETTINGS = [
    {"participants": 12, "trials": 4, "seed": 3},
    {"participants": 9, "trials": 5, "catch_trials": 1, "repeat_trials": 2, "inattentive": 0.3,
     "speeders": 0.2, "position_bias": 0.4, "tie_rate": 0.3, "clips_per_trial": 3,
     "clip_sd": 0.5, "noise": 0.7, "seed": 11,
     "strengths": {"real": 2.0, "x": 1.5, "y": 0.5, "z": -1.0}},
]


def table_hash(frame) -> str:
    """Return a SHA-256 of a table's columns, dtypes and values (but the constant
    ``simulated`` column, added after the recording: the draws are what must not change)."""
    frame = frame.drop(columns=["simulated"], errors="ignore")
    text = json.dumps([list(frame.columns), [str(t) for t in frame.dtypes]]) + frame.to_csv()
    return hashlib.sha256(text.encode()).hexdigest()


def hashes(study_type: str) -> list[str]:
    return [table_hash(simulate(study_type, **settings)) for settings in SETTINGS]


@pytest.mark.parametrize("study_type", list_analyses())
def test_simulate_writes_the_recorded_tables(study_type):
    recorded = json.loads(RECORD.read_text())
    if study_type not in recorded:
        pytest.skip("a type added after the recording has no earlier table to match")
    assert hashes(study_type) == recorded[study_type]


if __name__ == "__main__":  # records today's tables
    RECORD.write_text(json.dumps({t: hashes(t) for t in list_analyses()}, indent=1) + "\n")
