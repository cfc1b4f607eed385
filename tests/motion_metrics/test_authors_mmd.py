"""The authors' MMD protocol: hip-centred, depth-scaled poses, their estimator, both sides."""

import json

import numpy as np
import pytest
from django.core.management import call_command

from generation.sampling import sample_real
from motion.datasets import get_dataset
from motion.formats import npz
from motion.skeletons import get_skeleton
from motion_metrics import metrics as M
from motion_metrics.authors_mmd import Representation, authors_mmd, paired_mmd
from motion_metrics.protocol import MotionSet

SKELETON = get_skeleton("h36m15_2d")


def figures(count, frames=6, seed=0):
    """Return ``count`` random 2D figures near a standing pose, (N, T, 15, 2) pixels."""
    rng = np.random.default_rng(seed)
    base = rng.normal(0, 40, size=(1, 1, SKELETON.n_joints, 2))
    return base + rng.normal(0, 5, size=(count, frames, SKELETON.n_joints, 2)) + 500


def test_the_representation_ignores_where_the_figure_is_and_how_far_away():
    """Centred on the hips in every frame and scaled by the size-based depth ratio: a figure
    moved about the image and seen twice as far (half the size) is the same pose."""
    joints = figures(8)
    represent = Representation(SKELETON, figures(40, seed=1))
    hip = joints[:, :, [SKELETON.index("RHip"), SKELETON.index("LHip")]].mean(2, keepdims=True)
    moved = (joints - hip) * 0.5 + np.array([120.0, -60.0]) + np.arange(6)[None, :, None, None]
    assert np.allclose(represent(moved), represent(joints), atol=1e-9)
    assert np.allclose(represent.depth_ratio(moved), 2 * represent.depth_ratio(joints))
    with pytest.raises(M.MetricError, match="2D setting of seeds 003/004"):
        Representation(get_skeleton("h36m17"), np.zeros((2, 3, 17, 3)))


def test_paired_mmd_is_the_paired_estimate_of_every_frame():
    rng = np.random.default_rng(2)
    x, y = rng.normal(size=(12, 5, 4)), rng.normal(0.4, 1.2, size=(12, 5, 4))
    expected = np.mean([M.mmd_per_bandwidth(M.sq_dists(x[:, t]), M.sq_dists(y[:, t]),
                                            M.sq_dists(x[:, t], y[:, t]), paired=True)
                        for t in range(5)], axis=0).max()
    assert paired_mmd(x, y, True) == pytest.approx(expected)
    flat_x, flat_y = x.reshape(12, -1), y.reshape(12, -1)
    whole = M.mmd_per_bandwidth(M.sq_dists(flat_x), M.sq_dists(flat_y), M.sq_dists(flat_x, flat_y),
                                paired=True).max()
    assert paired_mmd(x, y, False) == pytest.approx(whole)


def test_both_sides_and_real_from_one_call():
    """Against the training clips (the authors' number), the held-out clips, and Real."""
    labels = np.repeat([0, 1], 30)
    train = MotionSet(figures(60, seed=3), labels)
    test = MotionSet(figures(60, seed=4) + 3.0, labels)
    same = MotionSet(train.joints.copy(), labels)
    found = authors_mmd(same, train, test, repeats=2, per_class=20, skeleton=SKELETON)
    for name in ("mmd_avg", "mmd_seq"):
        row = found[name]
        assert row["mmd_protocol"] == "authors" and row["per_class"] == 20
        assert len(row["values"]) == 2 and row["heldout"]["mean"] >= 0 and row["real"]["mean"] >= 0
    alone = authors_mmd(same, train, None, ["mmd_seq"], repeats=1, per_class=20, skeleton=SKELETON)
    assert alone["mmd_seq"]["heldout"] is None and alone["mmd_seq"]["real"] is None


def test_evaluate_command_prints_the_held_out_side(h36m_root, tmp_path, capsys):
    data = get_dataset("h36m2d", h36m_root)
    motions = sample_real(data, ["Walking", "Eating"], 6, seed=1, subjects=["S1", "S5"])
    path = tmp_path / "real.npz"
    npz.save(path, motions)
    out = tmp_path / "authors.json"
    call_command("evaluate", "--dataset", "h36m2d", "--data-root", str(h36m_root), "--motions",
                 str(path), "--metrics", "mmd_avg,mmd_seq", "--repeats", "2", "--mmd-protocol",
                 "authors", "--json", str(out))
    result = json.loads(out.read_text())
    assert result["mmd_protocol"]["name"] == "authors"
    assert {"mean", "heldout", "real"} <= set(result["metrics"]["mmd_seq"])
    printed = capsys.readouterr().out
    assert "mmd_seq [authors]" in printed and "held-out clips" in printed
