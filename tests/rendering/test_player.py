"""Player payloads: quantised joints in the set's framing, each frame filmed as the
clip's video films it, one size per clip length."""

import struct

import numpy as np
import pytest

from rendering import Framing, get_style
from rendering.player import PayloadError, dither, payload, read, size, write_payloads
from tests.rendering.conftest import drifting_walk, make_figure, rising_figure, shaken_anchor


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
    assert {len(d) for d in data} == {size(30, 17)} == {3576}
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
    targets = framing.targets(motion, placed)
    assert np.abs(fields["targets"] - targets).max() <= fields["step"] / 2 + 1e-6
    assert fields["distance"] == pytest.approx(framing.distance)
    assert np.allclose(fields["distances"], framing.distance)
    assert not fields["windows"].any()  # a steady walk: the rule's own frame
    assert list(fields["parents"]) == [-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15]
    assert set(fields["sides"]) == {-1, 0, 1}
    assert (fields["body_radii"] > fields["step"]).all()


def test_bad_payloads_are_refused_with_the_reason(clips):
    data = payload(clips[0], Framing.from_motions(clips))
    with pytest.raises(PayloadError, match="no MPLY header"):
        read(b"RIFF" + data[4:])
    with pytest.raises(PayloadError, match="need"):
        read(data[:-2])


@pytest.mark.parametrize("style", ["stick", "mesh"])
def test_each_frame_is_filmed_as_the_video_films_it(tmp_path, style):
    """The payload carries the clip's shot (rendering.framing.Framing.shot) at the video's
    size, on the joints as the style films them with its reach: each frame's look-at,
    window and distance, quantised."""
    real = make_figure(frames=50, speed=1.2)
    clips = {"drift": drifting_walk(), "rise": rising_figure(), "anchor": shaken_anchor()}
    framing = Framing.from_motions([real, *clips.values()])
    width, height = 96, 128  # not square: windows are shares of the height
    written = write_payloads(list(clips.values()), tmp_path, framing, (width, height), style)
    drawer = get_style(style)(framing, width, height)
    reach = drawer.reach("h36m17")
    for (name, motion), (path, _) in zip(clips.items(), written):
        fields = read(path.read_bytes())
        filmed = drawer.filmed(motion)  # the mesh's soles lifted to the floor
        assert np.abs(fields["positions"] - filmed).max() <= fields["step"] / 2 + 1e-6
        shot = framing.shot(motion, width, height, reach, filmed)
        assert np.abs(fields["targets"] - shot.targets).max() <= fields["step"] / 2 + 1e-6
        pixels = fields["windows"] * height
        assert np.abs(pixels - shot.offsets).max() <= height / 8192, name
        assert np.allclose(fields["distances"], shot.framing.distance, rtol=1 / 4000), name
    moved = read(written[0][0].read_bytes())["windows"]
    assert np.abs(moved).max() > 0.05, "the drifting walk's window never moves"
    zoomed = read(written[2][0].read_bytes())["distances"]
    assert zoomed.min() > 1.05 * framing.distance, "the anchor's body, flung apart, is zoomed"


def test_old_payloads_are_refused_with_the_fix(clips):
    data = payload(clips[0], Framing.from_motions(clips))
    old = data[:4] + struct.pack("<H", 1) + data[6:]
    for reader in (read, lambda d: dither(d, np.random.default_rng(0))):
        with pytest.raises(PayloadError, match="version 1; this reads version 2.*rebuild the "
                                               "stimuli"):
            reader(old)
