"""Real clips' MMD against real clips: how it depends on the number of clips, the protocol and the cameras.

Run (what docs/RESULTS.md reports):

    .venv/bin/python benchmarks/bench_real_mmd.py --out docs/images/real_mmd_vs_clips.png \\
        [--repeats 5] [--counts 5,10,20,30,50]

On h36m2d (training subjects S1, S5, S6, S7, S8; held-out S9), per class ``n`` clips of
each side are drawn without replacement and paired, and MMD_avg and MMD_seq are the
authors' estimate (:func:`motion_metrics.authors_mmd.paired_mmd`, mean over the 10
classes), in two representations: ``paper`` (joints from the clip's start, standardised
by the training clips) and ``authors`` (hip-centred, depth-scaled, standardised). Two
pairs of sides: **held-out vs training** (the Real row of the results) and **training vs
training** (two disjoint draws of the training clips: what the estimate gives for one
distribution). The same held-out vs training MMD is also measured with the clips
projected onto each of the subject's four cameras (``--cameras all``; the authors' code
keeps camera 55011271 only). Last, the authors' depth ratio estimated from the figure's
size is set against the true ratio of the hip's depth (from the 3D data and camera) on
every frame of the held-out subject's takes. Prints Markdown tables; draws the figure.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from motion.datasets import get_dataset
from motion.datasets.h36m2d import CAMERA
from motion_metrics.recognition import Split
from motion.skeletons import H36M15_2D_FROM_17, get_skeleton
from motion_metrics.authors_mmd import Representation, paired_mmd
from motion_metrics.comparison import H36M_TEST, H36M_TRAIN, t_interval

SKELETON = get_skeleton("h36m15_2d")


def start_relative(joints: np.ndarray) -> np.ndarray:
    root = SKELETON.root
    start = joints[:, 0, root].copy()
    start[:, SKELETON.up_index] = 0.0
    return joints - start[:, None, None]


class Paper:
    """The ``paper`` protocol's representation: start-relative joints standardised by training."""

    def __init__(self, train_joints):
        flat = start_relative(train_joints).reshape(-1, SKELETON.n_joints * 2)
        self.mean, self.std = flat.mean(0), np.maximum(flat.std(0), 1e-9)

    def __call__(self, joints):
        moved = start_relative(joints)
        return (moved.reshape(*moved.shape[:2], -1) - self.mean) / self.std


def arrays(clips):
    return (np.stack([c.joints for c in clips]).astype(np.float64),
            np.array([c.action for c in clips]))


def real_mmd(a, la, b, lb, n, repeats, seed, disjoint=False):
    """Return per repeat the class-averaged (MMD_avg, MMD_seq) of n paired clips a side."""
    out = []
    for r in range(repeats):
        rng = np.random.default_rng([seed, r])
        avg, seq = [], []
        for action in np.unique(la):
            pool_a, pool_b = np.flatnonzero(la == action), np.flatnonzero(lb == action)
            if disjoint:  # two disjoint draws of one pool
                order = rng.permutation(pool_a)
                pick_a, pick_b = order[:n], order[n:2 * n]
                if len(pick_b) < n:
                    continue
            else:
                if min(len(pool_a), len(pool_b)) < n:
                    continue
                pick_a = rng.choice(pool_a, n, replace=False)
                pick_b = rng.choice(pool_b, n, replace=False)
            avg.append(paired_mmd(a[pick_a], b[pick_b], True))
            seq.append(paired_mmd(a[pick_a], b[pick_b], False))
        out.append((np.mean(avg), np.mean(seq)))
    return np.array(out)


def summary(values):
    ci = t_interval(values)
    return f"{np.mean(values):.3f}" + ("" if ci is None else f" ± {ci:.3f}")


def clips_of(camera):
    data = get_dataset("h36m2d")
    data.camera = camera
    train, test = Split(test_subjects=H36M_TEST, train_subjects=H36M_TRAIN).divide(data.clips())
    return train, test


def depth_check():
    """Return how the size-based depth ratio follows the hip's true depth ratio (held-out frames)."""
    h36m, flat = get_dataset("h36m"), get_dataset("h36m2d")
    cameras = flat.cameras()
    train_2d, train_z, test_2d, test_z = [], [], [], []
    for subjects, xy, zs in ((H36M_TRAIN, train_2d, train_z), (H36M_TEST, test_2d, test_z)):
        for take in h36m.load_takes(subjects=list(subjects), actions=flat.actions()).motions:
            camera = cameras[take.meta["subject"]][CAMERA]
            world = take.joints * 1000.0
            xy.append(camera.project(world)[:, list(H36M15_2D_FROM_17)])
            zs.append(((world[:, 0] - camera.T) @ camera.R.T)[:, 2])  # the hip's depth
    represent = Representation(SKELETON, np.concatenate(train_2d)[None])
    mean_z = np.concatenate(train_z).mean()
    estimate = represent.depth_ratio(np.concatenate(test_2d)[None])[0]
    truth = np.concatenate(test_z) / mean_z
    error = estimate / truth - 1
    return {"frames": len(truth), "correlation": float(np.corrcoef(estimate, truth)[0, 1]),
            "median_abs_error": float(np.median(np.abs(error))),
            "p90_abs_error": float(np.quantile(np.abs(error), 0.9)),
            "true_range": (float(truth.min()), float(truth.max()))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="figure (PNG; an SVG beside it)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--counts", default="5,10,20,30,50")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cameras", default="all", help="'all' or none ('')")
    args = parser.parse_args()
    counts = [int(n) for n in args.counts.split(",")]
    train, test = clips_of(CAMERA)
    (tr, ltr), (te, lte) = arrays(train), arrays(test)
    curves = {}
    for name, rep in (("paper", Paper(tr)), ("authors", Representation(SKELETON, tr))):
        a, b = rep(te), rep(tr)
        for n in counts:
            curves[name, "held-out vs training", n] = real_mmd(a, lte, b, ltr, n, args.repeats, args.seed)
            curves[name, "training vs training", n] = real_mmd(b, ltr, b, ltr, n, args.repeats,
                                                               args.seed, disjoint=True)
    print("| representation | sides | n per class | MMD_avg | MMD_seq |")
    print("|---|---|---:|---:|---:|")
    for (name, sides, n), values in curves.items():
        print(f"| {name} | {sides} | {n} | {summary(values[:, 0])} | {summary(values[:, 1])} |")
    if args.cameras == "all":
        print("\n| camera | n per class | MMD_avg (authors) | MMD_seq (authors) |")
        print("|---|---:|---:|---:|")
        n = max(c for c in counts if c <= 50)
        for camera in sorted(get_dataset("h36m2d").cameras()["S9"]):
            ctrain, ctest = clips_of(camera)
            (ctr, lctr), (cte, lcte) = arrays(ctrain), arrays(ctest)
            rep = Representation(SKELETON, ctr)
            values = real_mmd(rep(cte), lcte, rep(ctr), lctr, n, args.repeats, args.seed)
            print(f"| {camera} | {n} | {summary(values[:, 0])} | {summary(values[:, 1])} |")
    check = depth_check()
    print(f"\nDepth ratio from the figure's size against the hip's true depth ratio, "
          f"{check['frames']} held-out frames: correlation {check['correlation']:.3f}, median "
          f"|error| {check['median_abs_error']:.1%}, 90th percentile {check['p90_abs_error']:.1%} "
          f"(true ratio {check['true_range'][0]:.2f}-{check['true_range'][1]:.2f})")
    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        from matplotlib import pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharex=True)
        for ax, index, label in ((axes[0], 0, "MMD_avg"), (axes[1], 1, "MMD_seq")):
            for (name, sides), style in ((("paper", "held-out vs training"), "C0-"),
                                         (("paper", "training vs training"), "C0:"),
                                         (("authors", "held-out vs training"), "C1-"),
                                         (("authors", "training vs training"), "C1:")):
                values = [curves[name, sides, n][:, index] for n in counts]
                means = [v.mean() for v in values]
                cis = [t_interval(v) or 0.0 for v in values]
                ax.errorbar(counts, means, yerr=cis, fmt=style, capsize=2, label=f"{name}: {sides}")
            ax.set_xlabel("clips per class (each side)")
            ax.set_ylabel(label)
            ax.set_ylim(bottom=0)
        axes[0].legend(fontsize=7)
        fig.suptitle("Real Human3.6M 2D clips: MMD against the number of clips (S9 held out)",
                     fontsize=9)
        fig.tight_layout()
        args.out.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.out, dpi=120)
        fig.savefig(args.out.with_suffix(".svg"))


if __name__ == "__main__":
    main()
