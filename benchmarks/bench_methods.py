"""Training seconds per iteration and sampling throughput of every registered method.

Run: .venv/bin/python benchmarks/bench_methods.py [--dataset demo] [--iters 3] [--n 1000]

Each method is built with its ``paper`` preset on the dataset's clips (60 frames for the
3D datasets), trained for a warm-up iteration and then ``--iters`` timed iterations; for
methods trained in two phases (a pretrained frame/pose model first), the second phase is
timed too. Sampling draws ``--n`` motions of 60 frames (after a warm-up draw), timed in
wall seconds and in this process's CPU seconds (on a shared machine the second moves
less with other work). One torch thread per process, so figures are per core. Prints a
Markdown table.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from motion.datasets import get_dataset
from generation.methods import get_method, list_methods

PHASE_FIELDS = ("pretrain_iters", "pose_iterations")  # length of a first training phase


def build(name, dataset, clips, frames, **changes):
    cls = get_method(name)
    config = dataclasses.replace(cls.Config.preset("paper"), **changes)
    actions = sorted({clip.action for clip in clips})
    return cls(config, skeleton=dataset.skeleton, actions=actions, fps=dataset.clip_fps,
               frames=frames)


def seconds_per_iteration(method, clips, iters):
    method.fit(clips, iters=1, seed=0, progress=False)  # warm-up, and first-phase set-up
    start = time.perf_counter()
    method.fit(clips, iters=iters, seed=0, progress=False)
    return (time.perf_counter() - start) / iters


def sampling_rate(method, actions, n, frames):
    """Return motions per second of wall time and per second of this process's CPU time."""
    method.sample(actions[:1] * 8, frames=frames, seed=1)
    wanted = [actions[i % len(actions)] for i in range(n)]
    start, cpu = time.perf_counter(), time.process_time()
    method.sample(wanted, frames=frames, seed=2)
    return n / (time.perf_counter() - start), n / (time.process_time() - cpu)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="demo")
    parser.add_argument("--iters", type=int, default=3)
    parser.add_argument("--n", type=int, default=1000, help="motions to sample")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--methods", help="comma-separated subset")
    args = parser.parse_args()
    torch.set_num_threads(1)

    dataset = get_dataset(args.dataset)
    clips = dataset.clips(frames=args.frames, max_per_take=2)
    names = args.methods.split(",") if args.methods else list_methods()
    print(f"{len(clips)} clips of {args.frames} frames from {args.dataset!r}; "
          f"paper presets; 1 torch thread\n")
    print(f"load average {os.getloadavg()[0]:.1f} at the start\n")
    print("| method | training s/iteration | second phase s/iteration | "
          f"sampling motions/s ({args.frames} frames, wall) | motions per CPU second |")
    print("|---|---|---|---|---|")
    for name in names:
        method = build(name, dataset, clips, args.frames)
        first = seconds_per_iteration(method, clips, args.iters)
        phase = next((f for f in PHASE_FIELDS if hasattr(method.config, f)), None)
        second = "—"
        if phase:
            staged = build(name, dataset, clips, args.frames, **{phase: 1})
            second = f"{seconds_per_iteration(staged, clips, args.iters):.3f}"
            method = staged
        rate, cpu_rate = sampling_rate(method, method.actions, args.n, args.frames)
        print(f"| `{name}` | {first:.3f} | {second} | {rate:,.0f} | {cpu_rate:,.0f} |", flush=True)
    print(f"\nload average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
