"""The metrics against closed forms and direct loops, and the repeat protocol on small arrays."""

import itertools

import numpy as np
import pytest

from motion_metrics import protocol
from motion_metrics import metrics as M


def gaussian_features(n=400, dims=4, seed=0, shift=0.0):
    return np.random.default_rng(seed).normal(size=(n, dims)) + shift


def sequences(n=12, frames=5, joints=3, seed=0, shift=0.0):
    return np.random.default_rng(seed).normal(size=(n, frames, joints, 3)) + shift


def test_sq_dists_match_a_loop():
    x, y = gaussian_features(7, 5, 1), gaussian_features(4, 5, 2)
    expected = np.array([[np.sum((a - b) ** 2) for b in y] for a in x])
    assert np.allclose(M.sq_dists(x, y), expected)
    within = M.sq_dists(x)
    assert np.all(np.diag(within) == 0) and np.allclose(within, within.T)


def test_fid_of_a_set_with_itself_is_zero():
    feats = gaussian_features(300, 6)
    assert abs(M.fid(feats, feats)) < 1e-6


def test_fid_from_stats_matches_the_closed_form_for_diagonal_covariances():
    mu1, mu2 = np.array([0.0, 1.0, -2.0]), np.array([0.5, 0.0, 1.0])
    s1, s2 = np.array([1.0, 2.0, 0.5]), np.array([4.0, 0.5, 0.5])
    expected = np.sum((mu1 - mu2) ** 2) + np.sum(s1 + s2 - 2 * np.sqrt(s1 * s2))
    assert M.fid_from_stats(mu1, np.diag(s1), mu2, np.diag(s2)) == pytest.approx(expected, rel=1e-9)


def test_fid_of_samples_approaches_the_closed_form():
    rng = np.random.default_rng(3)
    a = rng.normal(0.0, 1.0, size=(20000, 1))
    b = rng.normal(2.0, 3.0, size=(20000, 1))
    expected = 2.0 ** 2 + 1.0 + 9.0 - 2 * 3.0  # |mu1 - mu2|^2 + s1 + s2 - 2 sqrt(s1 s2)
    assert M.fid(a, b) == pytest.approx(expected, rel=0.05)


def test_fid_rejects_mismatched_widths():
    with pytest.raises(M.MetricError, match="width"):
        M.fid(gaussian_features(10, 3), gaussian_features(10, 4))


def test_accuracy():
    assert M.accuracy([0, 1, 2, 2], [0, 1, 1, 2]) == 0.75


def test_diversity_matches_a_loop_with_the_same_draws():
    feats = gaussian_features(50, 30)
    value = M.diversity(feats, n_pairs=200, rng=np.random.default_rng(7))
    pairs = np.random.default_rng(7).integers(0, 50, size=(2, 200))
    expected = np.mean([np.linalg.norm(feats[i] - feats[j]) for i, j in zip(*pairs)])
    assert value == pytest.approx(expected, rel=1e-12)


def test_multimodality_matches_a_loop_with_the_same_draws():
    feats = gaussian_features(60, 30)
    labels = np.repeat([2, 0, 1], 20)
    value = M.multimodality(feats, labels, n_pairs=20, rng=np.random.default_rng(5))
    rng = np.random.default_rng(5)
    per_action = []
    for label in (0, 1, 2):
        members = np.flatnonzero(labels == label)
        first, second = rng.choice(members, size=(2, 20))
        per_action.append(np.mean([np.linalg.norm(feats[i] - feats[j]) for i, j in zip(first, second)]))
    assert value == pytest.approx(np.mean(per_action), rel=1e-12)


def test_mmd_is_zero_for_identical_sets_and_grows_with_a_shift():
    x = gaussian_features(80, 5)
    assert M.mmd(x, x) == 0.0
    values = [M.mmd(x, gaussian_features(80, 5, seed=1, shift=s)) for s in (0.0, 0.5, 1.0, 2.0)]
    assert values == sorted(values) and values[-1] > 5 * values[0]


def test_mmd_per_bandwidth_matches_the_unbiased_estimate_by_loops():
    x, y = gaussian_features(6, 2, 1), gaussian_features(5, 2, 2, shift=0.3)
    bandwidth = 2.0

    def k(a, b):
        return np.exp(-np.sum((a - b) ** 2) / bandwidth)

    xx = np.mean([k(x[i], x[j]) for i, j in itertools.permutations(range(6), 2)])
    yy = np.mean([k(y[i], y[j]) for i, j in itertools.permutations(range(5), 2)])
    xy = np.mean([k(a, b) for a in x for b in y])
    value = M.mmd_per_bandwidth(M.sq_dists(x), M.sq_dists(y), M.sq_dists(x, y), [bandwidth])
    assert value[0] == pytest.approx(np.sqrt(max(xx + yy - 2 * xy, 0.0)), rel=1e-10)


def test_mmd_avg_and_seq_are_zero_for_identical_sets_and_grow_with_a_shift():
    real, labels = sequences(16), np.repeat([0, 1], 8)
    assert M.mmd_avg(real, real, labels, labels) == 0.0
    assert M.mmd_seq(real, real, labels, labels) == 0.0
    near, far = sequences(16, seed=1, shift=0.2), sequences(16, seed=1, shift=1.0)
    assert M.mmd_avg(real, near, labels, labels) < M.mmd_avg(real, far, labels, labels)
    assert M.mmd_seq(real, near, labels, labels) < M.mmd_seq(real, far, labels, labels)


def test_mmd_avg_takes_the_maximum_of_the_frame_average():
    real, fake = sequences(10), sequences(10, seed=1, shift=0.5)
    per_frame = np.array([
        M.mmd_per_bandwidth(M.sq_dists(fake[:, t].reshape(10, -1)), M.sq_dists(real[:, t].reshape(10, -1)),
                            M.sq_dists(fake[:, t].reshape(10, -1), real[:, t].reshape(10, -1)))
        for t in range(real.shape[1])
    ])
    assert M.mmd_avg(real, fake) == pytest.approx(per_frame.mean(0).max(), rel=1e-12)


def test_subset_mmd_equals_mmd_on_each_subset():
    pool, reference = gaussian_features(10, 3), gaussian_features(8, 3, seed=1, shift=0.7)
    masks = np.random.default_rng(0).random((4, 10)) < 0.5
    masks[0, :] = True
    values = M.subset_mmd(M.sq_dists(pool), M.sq_dists(pool, reference), M.sq_dists(reference), masks)
    for r, mask in enumerate(masks):
        x = pool[mask]
        expected = M.mmd_per_bandwidth(M.sq_dists(x), M.sq_dists(reference), M.sq_dists(x, reference))
        assert np.allclose(values[:, r] ** 2, expected ** 2, atol=1e-8)  # float32 kernels


def test_subset_mmd_batches_over_leading_axes():
    pools = [gaussian_features(9, 3, seed=s) for s in (0, 1)]
    refs = [gaussian_features(7, 3, seed=s, shift=0.5) for s in (2, 3)]
    masks = np.random.default_rng(1).random((3, 9)) < 0.6
    blocks = [np.stack(b) for b in zip(*[(M.sq_dists(p), M.sq_dists(p, r), M.sq_dists(r))
                                          for p, r in zip(pools, refs)])]
    batched = M.subset_mmd(*blocks, masks)
    assert batched.shape == (2, len(M.BANDWIDTHS), 3)
    for i in range(2):
        single = M.subset_mmd(blocks[0][i], blocks[1][i], blocks[2][i], masks)
        assert np.allclose(batched[i] ** 2, single ** 2, atol=1e-8)


def test_apd_matches_a_direct_loop():
    motions = sequences(9)
    flat = motions.reshape(9, -1)
    expected = np.mean([np.linalg.norm(flat[i] - flat[j]) for i, j in itertools.permutations(range(9), 2)])
    assert M.apd(motions) == pytest.approx(expected, rel=1e-10)
    masks = np.zeros((2, 9))
    masks[0, :5] = masks[1, 3:] = 1
    subsets = M.subset_apd(np.sqrt(M.sq_dists(flat)), masks)
    assert subsets == pytest.approx([M.apd(motions[:5]), M.apd(motions[3:])], rel=1e-10)


def test_n_apd_is_100_for_real_data_and_scales_with_spread():
    real, labels = sequences(12), np.repeat([0, 1, 2], 4)
    assert M.n_apd(real, labels, real, labels) == pytest.approx(100.0)
    assert M.n_apd(2 * real, labels, real, labels) == pytest.approx(200.0)


def test_mode_homogeneity_matches_the_definition_by_loops():
    motions = sequences(12, seed=4)
    labels = np.repeat([0, 1], 6)
    modes = np.array([0, 0, 1, 1, 1, 2, 0, 1, 0, 1, 0, 1])

    def loop_apd(items):
        if len(items) < 2:
            return 0.0
        flat = [m.ravel() for m in items]
        return np.mean([np.linalg.norm(a - b) for a, b in itertools.permutations(flat, 2)])

    drops = []
    for label in (0, 1):
        group = [m for m, l in zip(motions, labels) if l == label]
        group_modes = modes[labels == label]
        whole = loop_apd(group)
        mode_apd = sum(
            np.sum(group_modes == k) * loop_apd([g for g, mk in zip(group, group_modes) if mk == k])
            for k in np.unique(group_modes)
        ) / len(group)
        drops.append((whole - mode_apd) / whole)
    assert M.mode_homogeneity(motions, labels, modes) == pytest.approx(100 * np.mean(drops), rel=1e-10)


def test_mode_homogeneity_is_high_for_tight_modes():
    rng = np.random.default_rng(0)
    centres = rng.normal(size=(3, 5, 2, 3)) * 10
    modes = np.repeat([0, 1, 2], 5)
    motions = centres[modes] + rng.normal(size=(15, 5, 2, 3)) * 0.01
    assert M.mode_homogeneity(motions, np.zeros(15), modes) > 95


def test_dist_e_is_the_mean_squared_distance():
    target = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    reached = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    assert M.dist_e(target, reached) == pytest.approx((1.0 + 4.0) / 2)


def test_mean_ci_is_a_t_interval_over_repeats():
    """t with R - 1 degrees of freedom and the sample deviation, not A2M's 1.96 x the
    population deviation (37 % narrower for R = 5)."""
    from scipy import stats

    mean, ci = M.mean_ci([1.0, 2.0, 3.0, 4.0])
    assert mean == 2.5
    assert ci == pytest.approx(stats.t.ppf(0.975, 3) * np.std([1, 2, 3, 4], ddof=1) / 2)
    values = [1.0, 2.0, 4.0, 3.0, 5.0]
    a2m = 1.96 * np.std(values) / np.sqrt(5)
    assert 1 - a2m / M.mean_ci(values)[1] == pytest.approx(0.37, abs=0.01)
    assert np.isnan(M.mean_ci([2.0])[1]) and M.mean_ci([2.0])[0] == 2.0


def motion_set(n, seed, shift=0.0, classes=2):
    rng = np.random.default_rng(seed)
    labels = np.arange(n) % classes
    feats = np.tanh(rng.normal(size=(n, 30)) + labels[:, None] + shift)
    return protocol.MotionSet(
        joints=sequences(n, seed=seed, shift=shift), labels=labels, features=feats,
        predictions=labels.copy(), end_targets=rng.normal(size=(n, 3)), end_points=rng.normal(size=(n, 3)),
    )


def test_protocol_reports_every_metric_with_mean_ci_and_real():
    generated, test, train = motion_set(24, 0, shift=0.5), motion_set(16, 1), motion_set(20, 2)
    test.modes = np.arange(16) % 3  # mode homogeneity groups the real test clips
    test.end_targets = train.end_targets = None
    result = protocol.run(generated, test, train, repeats=3, seed=0)
    assert set(result["metrics"]) == set(protocol.METRICS) and not result["skipped"]
    for name, row in result["metrics"].items():
        assert np.isfinite(row["mean"]) and row["ci"] >= 0 and len(row["values"]) == 3, name
        assert (row["real"] is None) == (name in protocol.GENERATED_ONLY)
    assert result["metrics"]["accuracy"]["mean"] == 1.0
    assert result["metrics"]["n_apd"]["real"]["mean"] > 0


def test_protocol_pairwise_values_equal_the_metrics_on_each_draw():
    generated, test, train = motion_set(20, 0, shift=0.3), motion_set(12, 1), motion_set(12, 2)
    result = protocol.run(generated, test, train, ["mmd_seq", "mmd_avg", "apd", "fid"], repeats=2, seed=4)
    for r in range(2):
        draw = protocol._draw(generated, test, train, np.random.default_rng([4, r]))
        distinct = np.unique(draw["gen"])
        joints, labels = generated.joints[distinct], generated.labels[distinct]
        assert result["metrics"]["mmd_seq"]["values"][r] == pytest.approx(
            M.mmd_seq(test.joints, joints, test.labels, labels), abs=1e-6)
        assert result["metrics"]["mmd_avg"]["values"][r] == pytest.approx(
            M.mmd_avg(test.joints, joints, test.labels, labels), abs=1e-6)
        apds = [M.apd(joints[labels == c]) for c in (0, 1)]
        assert result["metrics"]["apd"]["values"][r] == pytest.approx(np.mean(apds), rel=1e-9)
        assert result["metrics"]["fid"]["values"][r] == pytest.approx(
            M.fid(generated.features[draw["gen"]], test.features[draw["ref"]]), rel=1e-9)


def test_protocol_mode_homogeneity_is_of_each_draw_of_real_test_clips():
    """Seed 001, Sec. 4.3.1: real clips grouped by their code modes; no Real column."""
    generated, test, train = motion_set(20, 0, shift=0.3), motion_set(18, 1), motion_set(12, 2)
    test.modes = np.arange(18) % 3
    result = protocol.run(generated, test, train, ["mode_homogeneity"], repeats=3, seed=2)
    row = result["metrics"]["mode_homogeneity"]
    assert row["real"] is None
    for r in range(3):
        draw = protocol._draw(generated, test, train, np.random.default_rng([2, r]))
        distinct = np.unique(draw["ref"])
        expected = M.mode_homogeneity(test.joints[distinct], test.labels[distinct], test.modes[distinct])
        assert row["values"][r] == pytest.approx(expected, rel=1e-9)
    shuffled = motion_set(20, 5, shift=2.0)  # other generated motions: the same value
    again = protocol.run(shuffled, test, train, ["mode_homogeneity"], repeats=3, seed=2)
    assert again["metrics"]["mode_homogeneity"]["values"] == row["values"]


def test_a2m_protocol_uses_a_fresh_set_per_repeat_whole_and_real_resamples_the_test_clips():
    test, train = motion_set(16, 1), motion_set(20, 2)
    sets = [motion_set(12, 10 + r, shift=0.5) for r in range(3)]
    names = ["fid", "accuracy", "mmd_seq", "apd"]
    made = []

    def fresh(r):
        made.append(r)
        return sets[r]

    result = protocol.run(fresh, test, train, names, repeats=3, seed=1, real_reference="test")
    assert made == [0, 1, 2]  # one set at a time, in order
    assert result["protocol"]["generated"] == "a fresh set per repeat"
    assert "held-out clips against another draw of the held-out clips" == result["protocol"]["real"]
    assert protocol.run(sets, test, train, names, repeats=3, seed=1, real_reference="test") == result
    for r, one in enumerate(sets):
        draw = protocol._draw(one, test, test, np.random.default_rng([1, r]), resample=False)
        assert sorted(draw["gen"]) == list(range(12))  # the whole set, once
        row = result["metrics"]
        assert row["fid"]["values"][r] == pytest.approx(M.fid(one.features, test.features[draw["ref"]]))
        assert row["mmd_seq"]["values"][r] == pytest.approx(
            M.mmd_seq(test.joints, one.joints, test.labels, one.labels), abs=1e-6)
        assert row["apd"]["values"][r] == pytest.approx(
            np.mean([M.apd(one.joints[one.labels == c]) for c in (0, 1)]), rel=1e-9)
        # Real: a draw of test clips against another draw of the same test clips.
        assert row["fid"]["real"]["values"][r] == pytest.approx(
            M.fid(test.features[draw["real"]], test.features[draw["real_ref"]]))
    default = protocol.run(sets[0], test, train, names, repeats=3, seed=1)
    assert default["protocol"]["generated"] == "resampled with replacement per repeat"
    assert default["protocol"]["real"] == "held-out clips against training clips"
    with pytest.raises(M.MetricError, match="one MotionSet per repeat: 3 repeats, got 2"):
        protocol.run(sets[:2], test, train, names, repeats=3)
    with pytest.raises(M.MetricError, match="real_reference must be 'train' or 'test'"):
        protocol.run(sets[0], test, train, names, real_reference="both")


def test_protocol_skips_metrics_lacking_inputs_and_rejects_unknown_ones():
    generated, test, train = motion_set(10, 0), motion_set(10, 1), motion_set(10, 2)
    generated.features = generated.predictions = None
    result = protocol.run(generated, test, train, ["fid", "mmd_seq", "mode_homogeneity"], repeats=2)
    assert set(result["metrics"]) == {"mmd_seq"}
    assert "classifier" in result["skipped"]["fid"]
    assert "mode of each real test clip" in result["skipped"]["mode_homogeneity"]
    generated.modes = np.arange(10) % 2  # modes of generated motions do not stand in
    assert "mode_homogeneity" in protocol.run(generated, test, train, ["mode_homogeneity"],
                                                repeats=1)["skipped"]
    with pytest.raises(M.MetricError, match="unknown metric 'fidd'"):
        protocol.run(generated, test, train, ["fidd"])


def test_protocol_needs_real_clips_of_every_action():
    generated, test, train = motion_set(10, 0, classes=3), motion_set(10, 1), motion_set(10, 2)
    with pytest.raises(M.MetricError, match="no motions of action 2"):
        protocol.run(generated, test, train, ["mmd_seq"], repeats=1)


def test_paper_mmd_compares_equal_counts_of_standardised_generated_and_training_motions():
    def make(n_per_action, seed, shift=0.0):
        labels = np.repeat([0, 1], n_per_action)
        return protocol.MotionSet(sequences(len(labels), seed=seed, shift=shift), labels)

    train, test = make(8, 0), make(5, 1)
    close, far = make(6, 2), make(6, 3, shift=2.0)
    near = protocol.paper_mmd(close, train, test, repeats=3, seed=0)
    away = protocol.paper_mmd(far, train, test, repeats=3, seed=0)
    assert set(near) == {"mmd_avg", "mmd_seq"} and near["mmd_seq"]["mmd_protocol"] == "paper"
    for name in ("mmd_avg", "mmd_seq"):
        assert len(near[name]["values"]) == 3 and near[name]["mean"] < away[name]["mean"]
        assert near[name]["real"]["mean"] == away[name]["real"]["mean"]  # Real ignores the motions
    # Repeat 0 by hand: per action, 6 generated and 6 of the 8 training clips, without replacement,
    # every coordinate standardised by the training clips.
    rng = np.random.default_rng([0, 0, 2])
    idx, ref = [], []
    for action in (0, 1):
        idx.append(rng.choice(np.flatnonzero(far.labels == action), 6, replace=False))
        ref.append(rng.choice(np.flatnonzero(train.labels == action), 6, replace=False))
        rng.choice(np.flatnonzero(test.labels == action), 5, replace=False)
        rng.choice(np.flatnonzero(train.labels == action), 5, replace=False)
    idx, ref = np.concatenate(idx), np.concatenate(ref)
    flat = train.joints.reshape(-1, 9)
    norm = lambda s: (s.joints.reshape(len(s.joints), 5, 9) - flat.mean(0)) / flat.std(0)  # noqa: E731
    x, y = norm(far)[idx].reshape(12, -1), norm(train)[ref].reshape(12, -1)
    expected = []
    for rows in (slice(0, 6), slice(6, 12)):  # paired: the cross term leaves out k(x_i, y_i)
        squared = []
        for b in M.BANDWIDTHS:
            k = lambda a, c: np.exp(-M.sq_dists(a, c) / b)  # noqa: E731
            kxx, kyy, kxy = k(x[rows], x[rows]), k(y[rows], y[rows]), k(x[rows], y[rows])
            off = ~np.eye(6, dtype=bool)
            squared.append(kxx[off].mean() + kyy[off].mean() - 2 * kxy[off].mean())
        expected.append(np.sqrt(max(max(squared), 0.0)))
    assert away["mmd_seq"]["values"][0] == pytest.approx(np.mean(expected))
    # Standardised coordinates: scaling and moving every set alike changes nothing.
    moved = [protocol.MotionSet(s.joints * 10.0 + 3.0, s.labels) for s in (far, train, test)]
    again = protocol.paper_mmd(*moved, repeats=3, seed=0)
    for name in ("mmd_avg", "mmd_seq"):
        assert np.allclose(again[name]["values"], away[name]["values"])
        assert np.allclose(again[name]["real"]["values"], away[name]["real"]["values"])
    with pytest.raises(M.MetricError, match="training clips have fewer than 2 motions of action 0, 1"):
        protocol.paper_mmd(far, make(1, 4), test)
    # Without held-out clips there is no Real column (the score that selects a checkpoint).
    alone = protocol.paper_mmd(far, train, None, ["mmd_seq"], repeats=3, seed=0)
    assert set(alone) == {"mmd_seq"} and alone["mmd_seq"]["real"] is None
    assert protocol.paper_mmd(close, train, None, ["mmd_seq"], 3)["mmd_seq"]["mean"] < alone["mmd_seq"]["mean"]
    first = [protocol.MotionSet(s.joints[s.labels == 0], s.labels[s.labels == 0]) for s in (far, train, test)]
    assert np.allclose(protocol.paper_mmd(first[0], first[1], None, repeats=3)["mmd_avg"]["values"],
                       protocol.paper_mmd(*first, repeats=3)["mmd_avg"]["values"])  # the same draws


def test_paired_mmd_needs_sets_of_equal_size():
    x, y = gaussian_features(5, 3, 1), gaussian_features(4, 3, 2)
    with pytest.raises(M.MetricError, match="paired MMD needs sets of equal size; got 5 and 4"):
        M.mmd_per_bandwidth(M.sq_dists(x), M.sq_dists(y), M.sq_dists(x, y), paired=True)
