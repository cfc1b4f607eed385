"""The catch clips of a build: a family per action (or prompt), not one clip for everyone.

Per action, :data:`CATCH_PER_BASE` broken versions (:func:`motion.perturb.catch_family`)
of one base clip of every source. A base is drawn as that source's judged clips are, one
more per action, so it is never a judged clip (cached as
``motions/<source>-catch-<key>.npz``); in a prompts study it is a judged clip of the
prompt, one per source, chosen by the seed. Catch clips made from every source are spread
in their numbers (bone lengths, speeds, jerk, heights) as the judged clips are, which
catch clips made from real clips alone would not be (generated clips' bones stretch, real
ones' do not). Of :data:`CANDIDATES` versions of each base, those kept are the ones that
bring the family's numbers, as a script reads them from the in-browser player's payload
(:func:`analysis.clip_features.payload_features`: bone lengths, speeds, jerk, heights,
ranges), closest to the judged clips' in mean and spread (:func:`keep_like`). The
study hands the least used one to each new participant (``assignment.pick_catch``), so
participants rarely share one.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections import defaultdict

import numpy as np

from analysis.clip_features import payload_features
from motion import ops, perturb
from motion.formats import npz
from motion.skeletons import get_skeleton
from rendering.player import payload
from studyapp.survey.models import Stimulus

Role = Stimulus.Role
# Broken versions of each base (one base per source and action): with three sources,
# six catch clips per action.
CATCH_PER_BASE = 2
CANDIDATES = 4  # broken versions drawn per base, of different kinds, to keep the best of
CATCH_STREAM = 7  # the family's random stream, beside the config's seed


def catch_clips(build, groups, framing) -> list[tuple]:
    """Return ``(motion, role, score)`` of a build's catch family (see the module docstring);
    ``groups`` are ``(source, judged motions, manifest fields)`` per source, ``framing``
    the study's."""
    if not build.roles().get(Role.CATCH):
        return []
    rng = np.random.default_rng([build.config.seed, CATCH_STREAM])
    by_action = defaultdict(list)
    for source, motions, meta in groups:
        for motion in catch_bases(build, source, motions, meta):
            by_action[motion.action].append(motion)
    candidates = [versions for action in sorted(by_action)
                  for versions in perturb.catch_candidates(by_action[action], CANDIDATES, rng)]
    judged = [m for _, motions, _ in groups for m in motions]
    return [(m, Role.CATCH, None) for m in keep_like(judged, candidates, framing)]


def prompt_catch_clips(build, groups, framing) -> list[tuple]:
    """Return the catch family of a prompts study: per prompt, broken versions of one
    judged clip of each source (chosen by the seed)."""
    if not build.roles().get(Role.CATCH):
        return []
    rng = np.random.default_rng([build.config.seed, CATCH_STREAM])
    by_prompt = defaultdict(lambda: defaultdict(list))
    for source, motions, _ in groups:
        for motion in motions:
            by_prompt[motion.action][source.name].append(motion)
    candidates = []
    for per_source in by_prompt.values():
        bases = [mine[int(rng.integers(len(mine)))] for mine in per_source.values()]
        candidates += perturb.catch_candidates(bases, CANDIDATES, rng)
    judged = [m for _, motions, _ in groups for m in motions]
    return [(m, Role.CATCH, None) for m in keep_like(judged, candidates, framing)]


def _numbers(motions, framing) -> list[dict]:
    return [payload_features({"motion": ({}, payload(ops.canonical(m, 3), framing))})
            for m in motions]


def keep_like(judged, candidates, framing, keep: int = CATCH_PER_BASE) -> list:
    """Return ``keep`` of each base's broken versions (``candidates``, a list per base),
    chosen so that the kept ones' payload numbers match the ``judged`` clips' in mean and
    in mean square, feature by feature (standardised on the judged clips): greedily base
    after base, then once more with every other base's choice known. 2D skeletons (no
    payload) keep the first ``keep`` of each."""
    flat = [m for versions in candidates for m in versions]
    if not flat or not judged or get_skeleton(flat[0].skeleton).dims != 3:
        return [m for versions in candidates for m in versions[:keep]]
    rows = _numbers(judged, framing)
    names = sorted(set().union(*rows))
    table = np.array([[row.get(n, 0.0) for n in names] for row in rows])
    mean, spread = table.mean(axis=0), table.std(axis=0)
    useful = spread > 1e-9 * (np.abs(mean) + 1.0)
    mean, spread = mean[useful], spread[useful]

    def standard(motions):
        found = _numbers(motions, framing)
        values = np.array([[row.get(n, 0.0) for n in names] for row in found])[:, useful]
        return np.nan_to_num((values - mean) / spread)

    scores = [standard(versions) for versions in candidates]
    options = [list(itertools.combinations(range(len(v)), min(keep, len(v)))) for v in candidates]
    choices: list = [None] * len(candidates)

    def mismatch(first, second, count):
        return float(((first / count) ** 2).sum() + ((second / count - 1.0) ** 2).sum())

    for _ in range(2):  # greedily, then again knowing every other base's choice
        for b in range(len(candidates)):
            others = [(scores[a][list(c)]) for a, c in enumerate(choices)
                      if c is not None and a != b]
            first = sum((o.sum(axis=0) for o in others), np.zeros(len(mean)))
            second = sum(((o ** 2).sum(axis=0) for o in others), np.zeros(len(mean)))
            count = sum(len(o) for o in others)
            choices[b] = min(options[b], key=lambda c: mismatch(
                first + scores[b][list(c)].sum(axis=0),
                second + (scores[b][list(c)] ** 2).sum(axis=0), count + len(c)))
    return [candidates[b][k] for b in range(len(candidates)) for k in choices[b]]


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
