"""Player payloads: quantised joints in the set's framing, one size per clip length."""

import numpy as np
import pytest

from rendering import Framing
from rendering.player import PayloadError, payload, read, size, write_payloads
from tests.rendering.conftest import make_figure


@pytest.fixture
def clips():
    walker = make_figure(frames=30, speed=1.5, source="secretmethod", action="zebracrossing")
    still = walker.with_joints(np.repeat(walker.joints[:1], 30, axis=0), source="real")
    rng = np.random.default_rng(0)
    broken = walker.with_joints((walker.joints + rng.normal(scale=0.3, size=walker.joints.shape))
                                .astype(np.float32), source="broken")
    return [walker, still, broken]


def test_payloads_have_one_size_and_name_nothing(clips, tmp_path):
    framing = Framing.from_motions(clips)
    data = [payload(m, framing) for m in clips]
    assert {len(d) for d in data} == {size(30, 17)}
    for blob in data:
        for secret in (b"secretmethod", b"zebracrossing", b"real", b"broken", b"h36m"):
            assert secret not in blob
    written = write_payloads(clips, tmp_path, framing)
    assert [p.name for p, _ in written] == [f"{h}.motion" for _, h in written]
    assert len({h for _, h in written}) == 3


def test_payload_round_trip_keeps_the_placed_joints_and_camera(clips):
    framing = Framing.from_motions(clips)
    motion = clips[0]
    fields = read(payload(motion, framing))
    placed = framing.place(motion)
    assert fields["frames"] == 30 and fields["joints"] == 17 and fields["fps"] == 25.0
    assert np.abs(fields["positions"] - placed).max() <= fields["step"] / 2 + 1e-6
    targets = framing.targets(motion, placed)[:, :2]
    assert np.abs(fields["targets"] - targets).max() <= fields["step"] / 2 + 1e-6
    assert fields["distance"] == pytest.approx(framing.distance)
    assert fields["target_z"] == pytest.approx(framing.target[2])
    assert list(fields["parents"]) == [-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15]
    assert set(fields["sides"]) == {-1, 0, 1}
    assert (fields["body_radii"] > fields["step"]).all()


def test_bad_payloads_are_refused_with_the_reason(clips):
    data = payload(clips[0], Framing.from_motions(clips))
    with pytest.raises(PayloadError, match="no MPLY header"):
        read(b"RIFF" + data[4:])
    with pytest.raises(PayloadError, match="need"):
        read(data[:-2])
