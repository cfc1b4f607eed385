"""Time a prompts study from MDM outputs to a registered study: import, render, register.

    .venv/bin/python benchmarks/bench_prompts.py [--prompts 12] [--repetitions 3]
                                                 [--frames 60] [--size 480] [--json OUT]

Two models' ``results.npy`` in MDM's layout (``sample/generate.py``: ``motion``
``(N, 22, 3, T)``, ``text``, ``lengths``, ``num_samples``, ``num_repetitions``, 20 fps),
``prompts x repetitions`` motions each (default 12 x 3 = 36, 72 in all), are built with
the ``studies/mdm_pairwise.yaml`` preset (its prompts replaced by the files' prompts, one
clip per source and repetition, a catch clip per prompt) by ``build_stimuli`` in a fresh
SQLite database and an empty cache, so every clip is rendered. The phases are timed from
the build's own progress messages: import (reading both files and matching their motions
to the prompts), render (every clip, one framing), register (stimuli and study).
"""

import argparse
import json
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

SOURCES = ("model_a", "model_b")


def body(frames: int, rng) -> np.ndarray:
    """Return joints ``(T, 22, 3)``, y up, metres: a standing figure stepping forward with
    swinging arms and legs (SMPL's 22 joints in HumanML3D's order)."""
    x = [0, .06, -.06, 0, .09, -.09, 0, .09, -.09, 0, .1, -.1, 0, .07, -.07, 0, .17, -.17,
         .43, -.43, .68, -.68]
    y = [.93, .84, .84, 1.05, .48, .48, 1.18, .08, .08, 1.23, .02, .02, 1.45, 1.38, 1.38,
         1.6, 1.4, 1.4, 1.4, 1.4, 1.4, 1.4]
    rest = np.stack([x, y, np.zeros(22)], axis=1)
    t = np.arange(frames)[:, None]
    joints = np.repeat(rest[None], frames, axis=0)
    swing, speed, phase = rng.uniform(0.05, 0.25), rng.uniform(0.005, 0.03), rng.uniform(0, 6)
    wave = np.sin(0.4 * t[:, 0] + phase)
    joints[:, :, 2] += speed * t
    for joint, sign in ((20, 1), (21, -1), (18, .5), (19, -.5), (7, .6), (8, -.6), (10, .6),
                        (11, -.6)):
        joints[:, joint, 2] += sign * swing * wave
    return (joints + rng.normal(scale=0.003, size=joints.shape)).astype(np.float32)


def write_results(path: Path, prompts, repetitions, frames, seed):
    rng = np.random.default_rng(seed)
    n = len(prompts) * repetitions
    motion = np.stack([body(frames, rng) for _ in range(n)]).transpose(0, 2, 3, 1)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, {"motion": motion, "text": [prompts[i % len(prompts)] for i in range(n)],
                   "lengths": np.full(n, frames), "num_samples": len(prompts),
                   "num_repetitions": repetitions})


def cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)  # ffmpeg
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prompts", type=int, default=12)
    parser.add_argument("--repetitions", type=int, default=3)
    parser.add_argument("--frames", type=int, default=60, help="Frames per clip (20 fps).")
    parser.add_argument("--size", type=int, default=480, help="Render size in pixels.")
    parser.add_argument("--json", metavar="OUT", help="Also write the timings as JSON.")
    args = parser.parse_args()

    work = Path(tempfile.mkdtemp(prefix="bench-prompts-"))
    try:
        run(args, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def run(args, work: Path) -> None:
    os.environ.update(STUDY_VAR_DIR=str(work / "var"), DJANGO_SETTINGS_MODULE="studyapp.settings",
                      PYOPENGL_PLATFORM=os.environ.get("PYOPENGL_PLATFORM", "egl"))
    os.environ.pop("DATABASE_URL", None)
    os.environ.pop("STUDY_DATABASE_URL", None)
    import django
    from django.core.management import call_command

    django.setup()
    call_command("migrate", verbosity=0)
    from studyapp.stimuli.build import build_stimuli
    from studyapp.stimuli.config import load_config

    prompts = [f"a person walks forward, turns and waves {k + 1} times" for k in range(args.prompts)]
    files = []
    for i, source in enumerate(SOURCES):
        path = work / source / "results.npy"
        write_results(path, prompts if i == 0 else prompts[::-1], args.repetitions,
                      args.frames, seed=i)
        files.append(path)
    overrides = [f"sources.{i}.file={path}" for i, path in enumerate(files)]
    overrides += ["prompts_from=null", f"prompts={json.dumps(prompts)}",
                  f"clips_per_source={args.repetitions}", f"frames={args.frames}",
                  f"render.size={args.size}"]

    marks = {}
    start_wall, start_cpu = time.perf_counter(), cpu_seconds()

    def progress(done, total, message):
        now = time.perf_counter() - start_wall
        if message.startswith("sampled"):
            marks["import"] = now
        elif message.startswith("rendered") or message == "renders cached":
            marks["render"] = now
        elif message == "manifest written":
            marks["register"] = now

    config = load_config(ROOT / "studies" / "mdm_pairwise.yaml", overrides)
    result = build_stimuli(config, work / "build", progress=progress, cache=work / "cache")
    wall, cpu = time.perf_counter() - start_wall, cpu_seconds() - start_cpu
    study = result.study
    judged = study.stimuli.judged().count()
    catch = study.stimuli.filter(role="catch").count()
    phases = {"import": marks["import"], "render": marks["render"] - marks["import"],
              "register": marks["register"] - marks["render"]}
    motions = len(SOURCES) * args.prompts * args.repetitions
    load = os.getloadavg()[0]
    print(f"{motions} motions ({len(SOURCES)} results.npy of {args.prompts} prompts x "
          f"{args.repetitions} repetitions, {args.frames} frames) -> study {study.slug!r}: "
          f"{judged} judged + {catch} catch clips rendered at {args.size} px")
    print(f"wall {wall:.1f} s (import {phases['import']:.1f}, render {phases['render']:.1f}, "
          f"register {phases['register']:.1f}); CPU {cpu:.1f} s; {os.cpu_count()} cores, "
          f"load average {load:.1f}")
    if args.json:
        Path(args.json).write_text(json.dumps({
            "motions": motions, "clips": judged + catch, "size": args.size,
            "frames": args.frames, "wall_s": wall, "cpu_s": cpu, "phases_s": phases,
            "cores": os.cpu_count(), "load_average": load}, indent=1))


if __name__ == "__main__":
    main()
