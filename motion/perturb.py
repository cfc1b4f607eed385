"""Motion operations that make a clip worse on purpose: the broken clips of attention
checks (catch trials), the graded examples of a scoring standard and the low anchors of
MUSHRA-style trials. Each returns a new motion; the input is left alone.

Examples and anchors are shaken (:func:`jitter`): each joint of each frame moved by
Gaussian noise, a share of the figure's size (the largest side of the box around its
joints in a frame, the median over the clip), so it means the same on any skeleton and
unit.

Catch clips must be obviously broken to a person and yet, in their numbers, like the
clips judged beside them: a script reading the in-browser player's payload measures bone
lengths, speeds, jerk and value ranges, and shaken clips stood out in all of them (bone
lengths varying by 41 % where judged clips varied by at most 21 %). So a catch clip is
broken by turning whole bones: every bone keeps its length in every frame exactly as in
the base clip, and the motion stays as smooth as the base's. :func:`catch_family` makes
several broken versions of each base (kinds and parameters drawn from the seed); what a
person sees of each kind:

- ``bent_backwards``: the knees (and in half of them the elbows too) bend the wrong
  way, 45-75 degrees beyond straight on average, while the clip's motion goes on:
  bird's legs, arms folding outwards at the elbow.
- ``limbs_swapped``: the arms move as the legs did, turned upside down, and the legs as
  the arms did: the arms stride in the air above the shoulders while the legs hang and
  swing like arms, bending forwards at the knee.
- ``head_hanging``: the neck folded 135-170 degrees backwards, forwards or sideways:
  no head on the shoulders, it hangs upside down on the back, the chest or a shoulder.
- ``leaning``: the whole body stands tilted stiffly 35-55 degrees about its feet,
  forwards, backwards or sideways, from the first frame to the last, as no one can
  without falling.
- ``sliding`` (bases that travel half their height or more): the legs freeze in one
  pose of the clip while the body travels on: it glides over the floor like a statue
  on ice.

Time reversal is not among them: a walk played backwards reads as someone walking
backwards. Broken clips carry no body surface (imported vertices would show the
unbroken body).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from motion.motion import Motion
from motion.skeletons import get_skeleton

# Joint jitter, as a share of the figure's extent, of the example clip of each score of
# a five-step scoring standard; MUSHRA's low anchor.
STANDARD_NOISE = {5: 0.0, 4: 0.01, 3: 0.03, 2: 0.07, 1: 0.18}
ANCHOR_NOISE = 0.12
# How far a base must travel (net, per figure height) to be slid.
SLIDE_TRAVEL = 0.5
# How much a limb must bend (in a tenth of the frames) to be bent the other way.
BENDING = math.radians(25)
# How near a catch clip's numbers stay to its base's (catch_family): the mean squared
# log ratio of its profile, 0.1 being about 30 % off on average.
NEAR = 0.1
# What a kind used once more in the family weighs against the family's drift (catch_family).
SPREAD = 0.02
EPS = 1e-9


def extent(motion: Motion) -> float:
    """Return the figure's size: the largest side of the box around its joints in a frame,
    the median over the clip's frames."""
    per_frame = np.ptp(motion.joints, axis=1).max(axis=1)  # (T,)
    return float(np.median(per_frame))


def jitter(motion: Motion, noise: float, rng, source: str | None = None) -> Motion:
    """Return ``motion`` with each joint of each frame moved by Gaussian noise of
    ``noise`` x the figure's size (0 leaves it as is), labelled ``source`` when given."""
    joints = motion.joints
    shake = rng.normal(scale=noise * extent(motion), size=joints.shape) if noise > 0 else 0.0
    moved = (joints + shake).astype(np.float32)
    return motion.with_joints(moved, source=source or motion.source, meta=dict(motion.meta))


def standard_examples(motion: Motion, rng, source: str = "standard_example") -> dict:
    """Return ``{score: motion}``: one clip per score of a scoring standard, from
    ``motion`` as is (5) to badly broken (1)."""
    return {score: jitter(motion, noise, rng, source)
            for score, noise in sorted(STANDARD_NOISE.items())}


def low_anchor(motion: Motion, rng, source: str = "anchor") -> Motion:
    """Return a clearly degraded version of a real clip: the low anchor of MUSHRA trials."""
    return jitter(motion, ANCHOR_NOISE, rng, source)


# --- the body as bones -----------------------------------------------------------------


@dataclass(frozen=True)
class Limb:
    """An arm or a leg: its longest two consecutive bones meet at ``middle`` (the knee or
    elbow), from ``upper`` (hip, shoulder) to ``lower`` (ankle, wrist)."""

    side: str
    upper: int
    middle: int
    lower: int


@dataclass(frozen=True)
class Body:
    """What the breaks read of a skeleton: bone order, subtrees, limbs, head, up."""

    parents: tuple[int, ...]
    order: tuple[int, ...]  # every joint after its parent
    below: tuple[tuple[int, ...], ...]  # below[j]: j and every joint under it
    legs: tuple[Limb, ...]
    arms: tuple[Limb, ...]
    head: tuple[int, int] | None  # (the joint the neck hangs from, the neck's first joint)
    up: np.ndarray  # (D,) unit vector

    @classmethod
    def of(cls, motion: Motion) -> "Body":
        """Return the body of ``motion``'s skeleton: limbs are its sided chains (legs from
        the root, arms from elsewhere), the neck the centre chain reaching highest."""
        skeleton = get_skeleton(motion.skeleton)
        parents = skeleton.parents
        children: dict[int, list[int]] = {}
        for joint, parent in enumerate(parents):
            children.setdefault(parent, []).append(joint)
        order, stack = [], [skeleton.root]
        while stack:
            joint = stack.pop()
            order.append(joint)
            stack.extend(children.get(joint, []))
        below = []
        for joint in range(len(parents)):
            under, stack = [], [joint]
            while stack:
                at = stack.pop()
                under.append(at)
                stack.extend(children.get(at, []))
            below.append(tuple(sorted(under)))
        lengths = np.median(skeleton.bone_lengths(motion.joints.astype(np.float64)), axis=0)
        up = np.zeros(skeleton.dims)
        up[skeleton.up_index] = skeleton.up_sign
        heights = np.median(motion.joints.astype(np.float64) @ up, axis=0)
        legs, arms, head = [], [], None
        for chain in skeleton.chains:
            sides = {skeleton.side_of(j) for j in chain[1:]}
            if len(sides) == 1 and sides != {"centre"} and len(chain) >= 3:
                # The longest two consecutive bones: thigh and shin, upper arm and forearm.
                pair = max(range(1, len(chain) - 1),
                           key=lambda k: lengths[chain[k]] + lengths[chain[k + 1]])
                limb = Limb(sides.pop(), chain[pair - 1], chain[pair], chain[pair + 1])
                (legs if chain[0] == skeleton.root else arms).append(limb)
            elif sides == {"centre"} and chain[0] != skeleton.root:
                # The neck: a centre chain reaching the highest point.
                if head is None or heights[chain[-1]] > heights[head[2]]:
                    head = (chain[0], chain[1], chain[-1])
        return cls(parents, tuple(order), tuple(below), tuple(legs), tuple(arms),
                   head[:2] if head else None, up)


def _bones(joints: np.ndarray, parents) -> tuple[np.ndarray, np.ndarray]:
    """Return each bone's unit direction ``(T, J, D)`` and length ``(T, J)`` (root: 0)."""
    anchor = np.array([max(p, 0) for p in parents])
    vectors = joints - joints[:, anchor]
    lengths = np.linalg.norm(vectors, axis=-1)
    directions = vectors / np.maximum(lengths, EPS)[..., None]
    root = parents.index(-1)
    lengths[:, root] = 0.0
    directions[:, root] = 0.0
    return directions, lengths


def _rebuild(root: np.ndarray, directions: np.ndarray, lengths: np.ndarray, body: Body):
    """Return joints from the root's path and every bone's direction and length."""
    joints = np.zeros(directions.shape)
    for joint in body.order:
        parent = body.parents[joint]
        if parent < 0:
            joints[:, joint] = root
        else:
            joints[:, joint] = joints[:, parent] + directions[:, joint] * lengths[:, joint, None]
    return joints


def _rotate(vectors: np.ndarray, axis: np.ndarray | None, angle) -> np.ndarray:
    """Rotate ``vectors`` ``(T, K, D)`` by ``angle`` (radians, scalar or ``(T,)``) about
    unit ``axis`` ``(T, 3)`` (3D, Rodrigues' formula) or in the plane (2D)."""
    angle = np.broadcast_to(np.asarray(angle, dtype=np.float64), (len(vectors),))
    cos, sin = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    if vectors.shape[-1] == 2:
        x, y = vectors[..., :1], vectors[..., 1:]
        return np.concatenate([x * cos - y * sin, x * sin + y * cos], axis=-1)
    k = np.broadcast_to(axis[:, None, :], vectors.shape)
    along = (k * vectors).sum(axis=-1, keepdims=True)
    return vectors * cos + np.cross(k, vectors) * sin + k * along * (1 - cos)


def _smooth(values: np.ndarray, window: int) -> np.ndarray:
    """Return a moving average over time (edges repeated), same shape."""
    if window <= 1 or len(values) < 2:
        return values
    padded = np.concatenate([values[:1].repeat(window // 2, 0), values,
                             values[-1:].repeat(window - 1 - window // 2, 0)])
    kernel = np.ones(window) / window
    return np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="valid"), 0, padded)


def _lateral(joints: np.ndarray, body: Body, fps: float) -> np.ndarray | None:
    """Return the body's left-pointing horizontal axis per frame ``(T, 3)`` (None in 2D),
    from the hips (else the shoulders), smoothed over a fifth of a second."""
    if joints.shape[-1] != 3:
        return None
    for limbs in (body.legs, body.arms):
        left = [limb.upper for limb in limbs if limb.side == "left"]
        right = [limb.upper for limb in limbs if limb.side == "right"]
        if left and right:
            across = joints[:, left].mean(axis=1) - joints[:, right].mean(axis=1)
            break
    else:
        across = np.tile(np.roll(body.up, 1), (len(joints), 1))  # any horizontal axis
    across = across - (across @ body.up)[:, None] * body.up
    across = _smooth(across, max(1, int(round(fps / 5))))
    norm = np.linalg.norm(across, axis=-1, keepdims=True)
    if (norm < EPS).any():
        across = np.where(norm < EPS, np.roll(body.up, 1), across)
        norm = np.linalg.norm(across, axis=-1, keepdims=True)
    return across / norm


def _forward(lateral: np.ndarray, body: Body) -> np.ndarray:
    """Return the facing direction per frame from the left axis (left = up x forward)."""
    return np.cross(lateral, body.up)


def _travel(joints: np.ndarray, body: Body, height: float) -> float:
    """Return how far the root moves between the first and last frames, per height."""
    root = body.order[0]
    step = joints[-1, root] - joints[0, root]
    step = step - (step @ body.up) * body.up
    return float(np.linalg.norm(step) / max(height, EPS))


def _signed_bend(upper: np.ndarray, lower: np.ndarray, axis: np.ndarray | None) -> np.ndarray:
    """Return the angle from ``upper`` to ``lower`` bone directions ``(T, D)`` about
    ``axis`` (in the plane in 2D), radians."""
    if axis is None:
        cross = upper[:, 0] * lower[:, 1] - upper[:, 1] * lower[:, 0]
        return np.arctan2(cross, (upper * lower).sum(axis=-1))
    u = upper - (upper * axis).sum(-1, keepdims=True) * axis
    v = lower - (lower * axis).sum(-1, keepdims=True) * axis
    return np.arctan2((np.cross(u, v) * axis).sum(-1), (u * v).sum(-1))


# --- the kinds of break ------------------------------------------------------------------


def _flexion(directions: np.ndarray, limb: Limb, axis) -> np.ndarray:
    """Return how a limb bends at its middle joint per frame (radians, signed)."""
    return _signed_bend(directions[:, limb.middle], directions[:, limb.lower], axis)


def _bending(joints: np.ndarray, body: Body, fps: float) -> list[Limb]:
    """Return the limbs that bend at least ``BENDING`` at their middle in a tenth of
    the clip's frames (a walk's knees, a throw's elbows)."""
    directions, _ = _bones(joints, body.parents)
    axis = _lateral(joints, body, fps)
    return [limb for limb in body.legs + body.arms
            if np.percentile(np.abs(_flexion(directions, limb, axis)), 90) >= BENDING]


def bent_backwards(joints, body, fps, height, rng):
    """Bend the limbs that bend the other way (see the module docstring)."""
    limbs = _bending(joints, body, fps)
    beyond = math.radians(rng.uniform(15, 30))
    directions, lengths = _bones(joints, body.parents)
    axis = _lateral(joints, body, fps)
    for limb in limbs:
        bend = _flexion(directions, limb, axis)
        usual = float(np.median(bend))
        sign = math.copysign(1.0, usual)
        # Mirrored about the upper bone: as far bent, the other way (so the limb spans
        # what it spanned), and a little further.
        turn = -2 * bend - sign * beyond
        under = list(body.below[limb.lower])
        directions[:, under] = _rotate(directions[:, under], axis, turn)
    return _rebuild(joints[:, body.order[0]], directions, lengths, body)


def leg_out(joints, body, fps, height, rng):
    """Turn one leg out at the hip and hold it there (see the module docstring)."""
    leg = body.legs[int(rng.integers(len(body.legs)))]
    angle = math.radians(rng.uniform(70, 110))
    directions, lengths = _bones(joints, body.parents)
    lateral = _lateral(joints, body, fps)
    axis = None
    if lateral is None:
        angle *= 1 if rng.integers(2) else -1
    else:
        side = 1.0 if leg.side == "left" else -1.0
        towards = [side * lateral, _forward(lateral, body), -_forward(lateral, body)]
        where = towards[int(rng.integers(3))]
        axis = np.cross(where, body.up)  # turns a leg hanging down towards ``where``
    under = list(body.below[leg.middle])
    directions[:, under] = _rotate(directions[:, under], axis, angle)
    return _rebuild(joints[:, body.order[0]], directions, lengths, body)


def limbs_swapped(joints, body, fps, height, rng):
    """Give the arms the legs' motion upside down and the legs the arms' (see the
    module docstring)."""
    directions, lengths = _bones(joints, body.parents)
    swapped = directions.copy()
    crossed = bool(rng.integers(2)) and len(body.legs) == len(body.arms) == 2
    legs = sorted(body.legs, key=lambda limb: limb.side)
    arms = sorted(body.arms, key=lambda limb: limb.side, reverse=crossed)
    for arm, leg in zip(arms, legs):
        for a, b in ((arm.middle, leg.middle), (arm.lower, leg.lower)):
            upward = directions[:, b] - 2 * (directions[:, b] @ body.up)[:, None] * body.up
            swapped[:, a], swapped[:, b] = upward, directions[:, a]
    return _rebuild(joints[:, body.order[0]], swapped, lengths, body)


def head_hanging(joints, body, fps, height, rng):
    """Fold the neck down backwards, forwards or sideways (see the module docstring)."""
    _, neck = body.head
    directions, lengths = _bones(joints, body.parents)
    angle = math.radians(rng.uniform(135, 170)) * (1 if rng.integers(2) else -1)
    lateral = _lateral(joints, body, fps)
    axis = None
    if lateral is not None:
        axis = lateral if rng.integers(3) else _forward(lateral, body)  # sideways a third
    under = list(body.below[neck])
    directions[:, under] = _rotate(directions[:, under], axis, angle)
    return _rebuild(joints[:, body.order[0]], directions, lengths, body)


def leaning(joints, body, fps, height, rng):
    """Tilt the whole body about its feet, all along (see the module docstring)."""
    frames = len(joints)
    angle = math.radians(rng.uniform(35, 55)) * (1 if rng.integers(2) else -1)
    floor = np.percentile((joints @ body.up).min(axis=1), 10)
    root = joints[:, body.order[0]]
    pivot = root - ((root @ body.up) - floor)[:, None] * body.up
    lateral = _lateral(joints, body, fps)
    axis = None
    if lateral is not None:
        first = lateral[0] if rng.integers(3) else _forward(lateral, body)[0]  # sideways a third
        axis = np.tile(first, (frames, 1))
    return _rotate(joints - pivot[:, None], axis, angle) + pivot[:, None]


def sliding(joints, body, fps, height, rng):
    """Freeze the legs in one pose while the body travels on (see the module docstring)."""
    frames = len(joints)
    held = int(rng.integers(frames // 4, max(frames // 4 + 1, 3 * frames // 4)))
    directions, lengths = _bones(joints, body.parents)
    under = sorted({j for leg in body.legs for j in body.below[leg.middle]})
    lateral = _lateral(joints, body, fps)
    if lateral is None:
        directions[:, under] = directions[held, under]
    else:
        # The pose is held in the body's own frame, so the legs turn with the hips.
        frame = np.stack([lateral, _forward(lateral, body),
                          np.tile(body.up, (frames, 1))], axis=1)  # (T, 3, 3) rows
        local = directions[held, under] @ frame[held].T  # (K, 3)
        directions[:, under] = np.einsum("kc,tcd->tkd", local, frame)
    return _rebuild(joints[:, body.order[0]], directions, lengths, body)


# name: (make, fits(body, facts)); facts: how far the base travels, which limbs bend.
KINDS = {
    "bent_backwards": (bent_backwards, lambda body, facts: bool(facts["bending"])),
    "leg_out": (leg_out, lambda body, facts: bool(body.legs)),
    "limbs_swapped": (limbs_swapped, lambda body, facts: bool(body.legs and body.arms)),
    "head_hanging": (head_hanging, lambda body, facts: body.head is not None),
    "leaning": (leaning, lambda body, facts: True),
    "sliding": (sliding, lambda body, facts: bool(body.legs) and facts["travel"] >= SLIDE_TRAVEL),
}


def kinds_for(motion: Motion) -> list[str]:
    """Return the kinds of break that fit ``motion`` (its skeleton, how far it travels,
    which limbs bend)."""
    body = Body.of(motion)
    joints = motion.joints.astype(np.float64)
    facts = {"travel": _travel(joints, body, extent(motion)),
             "bending": _bending(joints, body, motion.fps)}
    return [name for name, (_, fits) in KINDS.items() if fits(body, facts)]


def broken(motion: Motion, kind: str, rng, source: str = "broken") -> Motion:
    """Return ``motion`` broken by ``kind`` (one of :data:`KINDS`), parameters drawn from
    ``rng``; ``meta["broken"]`` names the kind."""
    if kind not in KINDS:
        raise KeyError(f"no kind of break {kind!r}; known: {', '.join(KINDS)}")
    body = Body.of(motion)
    joints = KINDS[kind][0](motion.joints.astype(np.float64), body, motion.fps,
                            extent(motion), rng)
    return motion.with_joints(joints.astype(np.float32), source=source, vertices=None,
                              faces=None, meta={**motion.meta, "broken": kind})


def profile(joints: np.ndarray, body: Body, fps: float) -> np.ndarray:
    """Return what a script measures of a clip's numbers, each as a positive number:
    the figure's height (the vertical extent of a frame: mean, spread, least, most), how
    high its lowest point is above the floor (mean and spread over frames, how far it
    sinks below), how high its highest and mean points are (and the mean's share of the
    height), its extent along each
    horizontal axis, how far its centre goes, and the mean, spread, 90th percentile and
    most of the joints' speeds, accelerations and jerk."""
    up = joints @ body.up  # (T, J)
    heights = up.max(axis=1) - up.min(axis=1)
    scale = max(float(np.median(heights)), EPS)
    floor = np.percentile(up.min(axis=1), 10)  # as the framing puts clips on the floor
    lowest = up.min(axis=1) - floor
    lengths = [heights.mean(), heights.std(), heights.min(), heights.max(),
               lowest.mean(), lowest.std(), -lowest.min(), up.max() - floor,
               up.mean() - floor]
    flat = joints - up[..., None] * body.up
    lengths += list(np.ptp(flat.reshape(-1, joints.shape[-1]), axis=0))
    centre = joints.mean(axis=1)
    lengths.append(np.linalg.norm(np.diff(centre, axis=0), axis=-1).sum() if len(joints) > 1
                   else 0.0)
    # Lengths are compared from a hundredth of the figure's height up, rates as they are;
    # where the body's mass sits in its height, as a share.
    out = [abs(value) + 0.01 * scale for value in lengths]
    out.append((up.mean() - floor) / max(heights.mean(), EPS) + 0.01)
    for order in (1, 2, 3):
        if len(joints) > order:
            rate = np.linalg.norm(np.diff(joints, order, axis=0), axis=-1) * fps ** order
            out += [rate.mean(), rate.std(), np.percentile(rate, 90), rate.max()]
        else:
            out += [0.0] * 4
    return np.asarray(out, dtype=float)


def _shift(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return profile ``a``'s log ratios to profile ``b``."""
    floor = 1e-9 * (np.abs(b).max() + 1e-9)
    return np.log((np.abs(a) + floor) / (np.abs(b) + floor))


def _unlike(a: np.ndarray, b: np.ndarray) -> float:
    """Return how far two profiles are apart: the mean squared log ratio."""
    return float((_shift(a, b) ** 2).mean())


def catch_family(bases: list[Motion], per_base: int, rng, source: str = "broken",
                 tries: int = 6) -> list[Motion]:
    """Return ``per_base`` broken versions of each base (catch clips), of different kinds,
    base after base (see :func:`catch_candidates`)."""
    return [m for versions in catch_candidates(bases, per_base, rng, source, tries)
            for m in versions]


def catch_candidates(bases: list[Motion], per_base: int, rng, source: str = "broken",
                     tries: int = 6) -> list[list[Motion]]:
    """Return, per base, ``per_base`` broken versions of it, of different kinds.

    Every kind that fits a base is drawn ``tries`` times (parameters from ``rng``); a
    version is a candidate when its numbers (:func:`profile`) stay within ``NEAR`` of
    the base's (else the nearest few are). Each pick is the candidate that keeps the
    family's numbers, summed over the versions kept so far, nearest their bases' (a
    version that makes the figure shorter is balanced by one that makes it taller), a
    kind the base has not had yet, the kinds least used so far in the family first.
    Catch clips are then spread in their numbers as the clips they are made from are,
    and in their kinds as widely as that allows.
    """
    made, used = [], {kind: 0 for kind in KINDS}
    drift = None  # the family's summed log ratios to its bases
    for base in bases:
        body = Body.of(base)
        target = profile(base.joints.astype(np.float64), body, base.fps)
        candidates = []
        for kind in kinds_for(base):
            for _ in range(tries):
                motion = broken(base, kind, rng, source)
                shift = _shift(profile(motion.joints.astype(np.float64), body, base.fps),
                               target)
                candidates.append((float((shift ** 2).mean()), kind, shift, motion))
        candidates.sort(key=lambda c: c[0])
        near = [c for c in candidates if c[0] <= NEAR]
        if len({c[1] for c in near}) < per_base:
            kinds = list(dict.fromkeys(c[1] for c in candidates))[:per_base]
            near = [c for c in candidates if c[0] <= NEAR or c[1] in kinds]
        drift = np.zeros_like(target) if drift is None else drift
        made.append([])
        for _ in range(per_base):
            if not near:
                break
            pick = min(near, key=lambda c: float(((drift + c[2]) ** 2).mean())
                       + SPREAD * used[c[1]])
            made[-1].append(pick[3])
            used[pick[1]] += 1
            drift = drift + pick[2]
            near = [c for c in near if c[1] != pick[1]]
    return made


def catch_clip(motion: Motion, rng, source: str = "broken") -> Motion:
    """Return one obviously broken version of ``motion`` (a kind that fits, at random)."""
    fitting = kinds_for(motion)
    return broken(motion, fitting[int(rng.integers(len(fitting)))], rng, source)
