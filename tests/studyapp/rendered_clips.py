"""Clips as the stimulus build makes them (padded mp4s and posters, player payloads), for
tests of what each delivery sends: write once per module with :func:`render_clips`."""

from pathlib import Path

import numpy as np

from motion import perturb
from rendering import Framing, render_set
from rendering.player import write_payloads
from tests.rendering.conftest import make_figure

ACTIONS = ("walk", "wave")
SOURCES = ("real", "a2m", "cond_gru")
FRAMES = 12
SIZE = 64


def motions(catch_per_action: int = 2) -> list:
    """Return judged motions (2 actions x 3 sources) and catch clips (broken versions)."""
    out = []
    for a, action in enumerate(ACTIONS):
        for s, source in enumerate(SOURCES):
            figure = make_figure(frames=FRAMES, speed=0.8 + 0.3 * s, action=action,
                                 source=source, phase=a + 0.7 * s)
            out.append(figure)
    rng = np.random.default_rng(5)
    for a, action in enumerate(ACTIONS):
        base = make_figure(frames=FRAMES, speed=1.2, action=action, phase=2.0 + a)
        out += [m.with_joints(m.joints, action=action) for m in
                perturb.catch_family([base], catch_per_action, rng)]
    return out


def render_clips(root: Path, catch_per_action: int = 2) -> list:
    """Render :func:`motions` into ``root``; return their ``Clip`` records (payloads too)."""
    from studyapp.stimuli.clips import Clip

    shown = motions(catch_per_action)
    framing = Framing.from_motions(shown)
    report = render_set(shown, root, size=SIZE, framing=framing, progress=False)
    payloads = write_payloads(shown, root / "payloads", framing, SIZE)
    clips = []
    for done, motion, (path, _) in zip(sorted(report.clips, key=lambda c: c.index), shown,
                                       payloads):
        role = "catch" if motion.source == "broken" else "judged"
        clip = Clip.rendered(motion, done, role=role)
        clips.append(Clip(**{**clip.__dict__, "motion": path}))
    return clips
