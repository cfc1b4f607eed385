"""The catch clips of a build: a family per action (or prompt), not one clip for everyone.

Per action, :data:`CATCH_PER_BASE` broken versions (:func:`generation.perturb.catch_family`)
of one base clip of every source. A base is drawn as that source's judged clips are, one
more per action, so it is never a judged clip (cached as
``motions/<source>-catch-<key>.npz``); in a prompts study it is a judged clip of the
prompt, one per source, chosen by the seed. Catch clips made from every source are spread
in their numbers (bone lengths, speeds, jerk, heights) as the judged clips are, which
catch clips made from real clips alone would not be (generated clips' bones stretch, real
ones' do not). The study hands the least used one to each new participant
(``assignment.pick_catch``), so participants rarely share one.
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict

import numpy as np

from generation import perturb
from generation.formats import npz
from studyapp.survey.models import Stimulus

Role = Stimulus.Role
# Broken versions of each base (one base per source and action): with three sources,
# six catch clips per action.
CATCH_PER_BASE = 2
CATCH_STREAM = 7  # the family's random stream, beside the config's seed


def catch_clips(build, groups) -> list[tuple]:
    """Return ``(motion, role, score)`` of a build's catch family (see the module docstring);
    ``groups`` are ``(source, judged motions, manifest fields)`` per source."""
    if not build.roles().get(Role.CATCH):
        return []
    rng = np.random.default_rng([build.config.seed, CATCH_STREAM])
    by_action = defaultdict(list)
    for source, motions, meta in groups:
        for motion in catch_bases(build, source, motions, meta):
            by_action[motion.action].append(motion)
    return [(m, Role.CATCH, None) for action in sorted(by_action)
            for m in perturb.catch_family(by_action[action], CATCH_PER_BASE, rng)]


def prompt_catch_clips(build, groups) -> list[tuple]:
    """Return the catch family of a prompts study: per prompt, broken versions of one
    judged clip of each source (chosen by the seed)."""
    if not build.roles().get(Role.CATCH):
        return []
    rng = np.random.default_rng([build.config.seed, CATCH_STREAM])
    by_prompt = defaultdict(lambda: defaultdict(list))
    for source, motions, _ in groups:
        for motion in motions:
            by_prompt[motion.action][source.name].append(motion)
    out = []
    for per_source in by_prompt.values():
        bases = [mine[int(rng.integers(len(mine)))] for mine in per_source.values()]
        out += [(m, Role.CATCH, None) for m in perturb.catch_family(bases, CATCH_PER_BASE, rng)]
    return out


def catch_bases(build, source, judged, meta) -> list:
    """Return one clip per action of ``source`` that is not judged: drawn as its judged
    clips are, one more per action (a file's next motion), cached; a judged clip where the
    source has no other (a file of exactly ``clips_per_source`` motions per action)."""
    n = build.config.clips_per_source + 1
    fields = {"source": source.section(), "data": build.data_fields(), **meta,
              "catch_bases": n}
    key = hashlib.sha256(json.dumps(fields, sort_keys=True, default=str).encode()).hexdigest()
    cached = build.cache / "motions" / f"{source.name}-catch-{key[:16]}.npz"
    if cached.is_file():
        return npz.load(cached)
    drawn = build.sample(source, n)
    taken = {m.content_hash() for m in judged}
    bases = []
    for action in dict.fromkeys(m.action for m in judged):
        fresh = [m for m in drawn if m.action == action and m.content_hash() not in taken]
        if not fresh:
            build.log(f"{source.name}: no clip of {action} beyond the judged ones; its catch "
                      f"clips are broken versions of a judged one")
            fresh = [m for m in judged if m.action == action]
        bases.append(fresh[-1])
    npz.save(cached, bases)
    return bases
