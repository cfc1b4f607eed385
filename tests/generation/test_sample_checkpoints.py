"""A fresh sample from a source's checkpoints: n in all, over actions and checkpoints."""

from collections import Counter

import pytest

from generation.sampling import SamplingError, sample_checkpoints
from tests.conftest import ROOT

CHECKPOINT = ROOT / "studies" / "demo" / "checkpoints" / "a2m.pt"


def test_n_motions_spread_over_actions_and_checkpoints():
    motions = sample_checkpoints([CHECKPOINT, CHECKPOINT], ["walk", "wave"], 7, frames=10, seed=3)
    assert len(motions) == 7 and all(m.frames == 10 for m in motions)
    assert Counter(m.action for m in motions) == {"walk": 4, "wave": 3}
    again = sample_checkpoints([CHECKPOINT, CHECKPOINT], ["walk", "wave"], 7, frames=10, seed=3)
    assert [m.content_hash() for m in motions] == [m.content_hash() for m in again]
    with pytest.raises(SamplingError, match="has no action 'fly'"):
        sample_checkpoints([CHECKPOINT], ["fly"], 2)
