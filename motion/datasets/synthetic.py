"""The ``demo`` dataset: SYNTHETIC motions, made procedurally, shipped with the code.

Nothing here is motion capture. Each take is built by forward kinematics from joint
angle curves written by hand (one small function per action), so bone lengths are
exactly constant within a take. Takes vary in speed, amplitude, style (arm swing phase,
which hand waves or throws, which leg kicks), body size (bone lengths scaled 0.85-1.15)
and heading. The lower foot stays on the ground (z = 0) except in flight, and the
stance foot does not slide, so walking and running move forward by themselves.

Skeleton ``h36m17``, metres, z up, 25 fps; bodies face +x (within 45 degrees), with
their left side towards +y.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from motion.datasets.base import Dataset, LoadReport, register_dataset
from motion.motion import Motion
from motion.skeletons import H36M17

FPS = 25.0
ACTIONS = ("walk", "run", "jump", "wave", "squat", "kick", "throw", "sit_down")

# Rest pose of a 1.75 m body: each joint's offset from its parent, arms hanging down.
REST_OFFSETS = {
    "Hip": (0.0, 0.0, 0.0),
    "RHip": (0.0, -0.13, 0.0),
    "RKnee": (0.0, 0.0, -0.44),
    "RFoot": (0.0, 0.0, -0.44),
    "LHip": (0.0, 0.13, 0.0),
    "LKnee": (0.0, 0.0, -0.44),
    "LFoot": (0.0, 0.0, -0.44),
    "Spine": (0.0, 0.0, 0.23),
    "Thorax": (0.0, 0.0, 0.26),
    "Neck/Nose": (0.04, 0.0, 0.10),
    "Head": (-0.02, 0.0, 0.09),
    "LShoulder": (0.0, 0.15, -0.03),
    "LElbow": (0.0, 0.0, -0.28),
    "LWrist": (0.0, 0.0, -0.25),
    "RShoulder": (0.0, -0.15, -0.03),
    "RElbow": (0.0, 0.0, -0.28),
    "RWrist": (0.0, 0.0, -0.25),
}

SIDES = {"left": ("L", 1.0), "right": ("R", -1.0)}


class Body:
    """Joint angle curves of one take, in radians, written in anatomical terms.

    Each joint holds (roll about x, pitch about y, yaw about z) per frame, applied to the
    joint's children; x points forward, y to the body's left, z up. ``lift`` raises the
    whole body off the ground (flight). ``stance`` names the foot that carries the body
    (``"left"``, ``"right"``, ``""`` for the lower one, ``"air"`` for none); it does
    not slide.
    """

    def __init__(self, frames: int):
        self.angles = {name: np.zeros((frames, 3)) for name in H36M17.joint_names}
        self.lift = np.zeros(frames)
        self.stance = np.full(frames, "", dtype=object)

    def leg(self, side, hip_flex=0.0, knee_flex=0.0, hip_abduct=0.0):
        """Swing the thigh forward / outward and bend the knee (shin goes back)."""
        prefix, outward = SIDES[side]
        self.angles[prefix + "Hip"][:, 0] += outward * hip_abduct
        self.angles[prefix + "Hip"][:, 1] -= hip_flex
        self.angles[prefix + "Knee"][:, 1] += knee_flex

    def arm(self, side, shoulder_flex=0.0, elbow_flex=0.0, shoulder_abduct=0.0,
            elbow_abduct=0.0):
        """Raise the upper arm forward / sideways; bend the forearm forward / sideways."""
        prefix, outward = SIDES[side]
        self.angles[prefix + "Shoulder"][:, 0] += outward * shoulder_abduct
        self.angles[prefix + "Shoulder"][:, 1] -= shoulder_flex
        self.angles[prefix + "Elbow"][:, 0] += outward * elbow_abduct
        self.angles[prefix + "Elbow"][:, 1] -= elbow_flex

    def trunk(self, lean=0.0, twist=0.0, side_bend=0.0):
        """Lean the upper body forward, twist it to the left, bend it to the left."""
        for joint, share in (("Spine", 0.6), ("Thorax", 0.4)):
            self.angles[joint][:, 1] += share * lean
            self.angles[joint][:, 2] += share * twist
            self.angles[joint][:, 0] -= share * side_bend

    def head(self, nod=0.0, turn=0.0):
        """Nod the head forward and turn it to the left."""
        self.angles["Neck/Nose"][:, 1] += nod
        self.angles["Neck/Nose"][:, 2] += turn

    def pelvis(self, tilt=0.0, turn=0.0):
        """Tilt the pelvis forward and turn it to the left (legs and trunk follow)."""
        self.angles["Hip"][:, 1] += tilt
        self.angles["Hip"][:, 2] += turn


def keyframes(phase, knots, values):
    """Ease between ``values`` at ``knots`` (cosine easing); ``phase`` wraps to [0, 1)."""
    phase = np.mod(phase, 1.0)
    knots = np.asarray(knots, dtype=float)
    values = np.asarray(values, dtype=float)
    segment = np.clip(np.searchsorted(knots, phase, side="right") - 1, 0, len(knots) - 2)
    span = knots[segment + 1] - knots[segment]
    s = np.clip((phase - knots[segment]) / span, 0.0, 1.0)
    eased = 0.5 - 0.5 * np.cos(np.pi * s)
    return values[segment] + (values[segment + 1] - values[segment]) * eased


def ramp(t, start, duration):
    """Return 0 before ``start``, 1 after ``start + duration``, eased between."""
    s = np.clip((t - start) / duration, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


def deg(x):
    """Return degrees in radians."""
    return np.deg2rad(x)


@dataclass
class Style:
    """The random choices of one take."""

    speed: float  # multiplies every frequency
    amplitude: float  # multiplies the main joint excursions
    phase: float  # where in its cycle the take starts, in [0, 1)
    arm_phase: float  # offset of the arm swing against the legs, radians
    side: str  # the hand that waves or throws, the leg that kicks

    @property
    def other(self) -> str:
        return "right" if self.side == "left" else "left"


def leg_cycle(phase, duty):
    """Return a leg's swing (about +1 front, -1 back), knee bends and stance flag.

    The foot lands at phase 0 and stays planted for ``duty`` of the cycle, while the
    thigh sweeps back at constant speed (so the body moves at an even pace); the swing
    back to the front is a cubic that leaves and lands with that same speed.
    Returns ``(swing, swing_bend, stance_bend, planted)``, bends in 0..1.
    """
    phase = np.mod(phase, 1.0)
    planted = phase < duty
    s_stance = np.clip(phase / duty, 0.0, 1.0)
    s_swing = np.clip((phase - duty) / (1.0 - duty), 0.0, 1.0)
    speed = -2.0 * (1.0 - duty) / duty  # stance sweep speed, in swing-phase units
    h00, h10 = 2 * s_swing**3 - 3 * s_swing**2 + 1, s_swing**3 - 2 * s_swing**2 + s_swing
    h01, h11 = -2 * s_swing**3 + 3 * s_swing**2, s_swing**3 - s_swing**2
    swing_curve = -h00 + h01 + (h10 + h11) * speed
    swing = np.where(planted, 1.0 - 2.0 * s_stance, swing_curve)
    # sin² bends start and end at rest; the knee is straight for the last fifth of the
    # swing, so the foot lands without a jolt.
    swing_bend = np.where(planted, 0.0, np.sin(np.pi * np.clip(s_swing / 0.8, 0.0, 1.0)) ** 2)
    stance_bend = np.where(planted, np.sin(np.pi * s_stance) ** 2, 0.0)
    return swing, swing_bend, stance_bend, planted


def gait(body, t, style, cadence, duty, hip, knee_swing, knee_stance, elbow, arm, lean):
    """Fill a walking or running gait: legs half a cycle apart, arms swinging against them.

    With ``duty`` below one half both feet are off the ground between steps.
    """
    phase = cadence * style.speed * t + style.phase
    planted = {}
    for side, shift in (("right", 0.0), ("left", 0.5)):
        swing, swing_bend, stance_bend, planted[side] = leg_cycle(phase + shift, duty)
        thigh = deg(5) + hip * style.amplitude * swing
        # A planted knee that bends would drag the foot; turning the thigh to keep the
        # foot where the straight leg puts it (thigh and shin are equally long) keeps the
        # foot's sweep, and so the body's speed, even.
        support = deg(5) + knee_stance * stance_bend
        thigh = support / 2 + np.arcsin(np.clip(np.sin(thigh) / np.cos(support / 2), -1, 1))
        body.leg(side, hip_flex=thigh,
                 knee_flex=support + knee_swing * style.amplitude * swing_bend)
        cycle = 2 * np.pi * (phase + shift)
        body.arm(side, shoulder_flex=-arm * style.amplitude * np.cos(cycle + style.arm_phase),
                 elbow_flex=elbow + deg(10) * np.cos(cycle), shoulder_abduct=deg(6))
    # Without ankles the swinging foot dips below the planted one just before it lands;
    # naming the planted foot keeps the body from stepping back then. With both feet
    # down, the one that landed first carries the body until it lifts.
    right_first = np.mod(phase, 1.0) >= np.mod(phase + 0.5, 1.0)
    body.stance = np.where(planted["right"] & (right_first | ~planted["left"]), "right",
                           np.where(planted["left"], "left", "air"))
    body.trunk(lean=lean, twist=deg(5) * np.cos(2 * np.pi * phase))
    body.pelvis(turn=-deg(4) * np.cos(2 * np.pi * phase))
    return phase


def walk(body, t, style):
    """Walk: about one stride per second, arms swinging against the legs."""
    gait(body, t, style, cadence=0.95, duty=0.6, hip=deg(20), knee_swing=deg(55),
         knee_stance=deg(12), elbow=deg(15), arm=deg(20), lean=deg(4))


def run(body, t, style):
    """Run: faster, deeper knee bend, bent elbows, leaning forward, short flights."""
    duty = 0.38
    phase = gait(body, t, style, cadence=1.4, duty=duty, hip=deg(30), knee_swing=deg(95),
                 knee_stance=deg(30), elbow=deg(85), arm=deg(35), lean=deg(12))
    # Airborne between the toe-off of one foot and the landing of the other.
    half = np.mod(phase, 0.5)
    flight = np.clip((half - duty) / (0.5 - duty), 0.0, 1.0)
    body.lift += 0.06 * style.amplitude * np.sin(np.pi * flight)


def jump(body, t, style):
    """Jump: crouch, swing the arms up, take off (a small hop forward), land, stand up."""
    phase = t / (1.6 / style.speed) + style.phase
    knots = (0.0, 0.15, 0.45, 0.55, 0.75, 0.85, 1.0)
    crouch = keyframes(phase, knots, (0, 0, 1.0, 0, 0.15, 0.7, 0))
    for side in ("left", "right"):
        body.leg(side, hip_flex=deg(70) * crouch, knee_flex=deg(110) * crouch)
        body.arm(side, shoulder_flex=keyframes(phase, knots, deg((0, 0, -45, 160, 120, -10, 0))),
                 elbow_flex=deg(15))
    body.trunk(lean=deg(35) * crouch)
    flight = np.clip((np.mod(phase, 1.0) - 0.55) / 0.2, 0.0, 1.0)
    body.lift += 0.25 * style.amplitude * np.sin(np.pi * flight)


def wave(body, t, style):
    """Wave: raise one arm to the side, forearm up, and wave it over the head."""
    raised = ramp(t, 0.2 + 0.4 * style.phase, 0.6)
    abduct = deg(115) * style.amplitude
    waving = deg(25) * np.sin(2 * np.pi * 2.0 * style.speed * t)
    body.arm(style.side, shoulder_abduct=abduct * raised,
             elbow_abduct=(np.pi - abduct + waving) * raised, elbow_flex=deg(10))
    body.arm(style.other, elbow_flex=deg(10), shoulder_abduct=deg(5))
    body.trunk(side_bend=-deg(4) * raised * SIDES[style.side][1])
    body.head(turn=deg(10) * SIDES[style.side][1] * raised)


def squat(body, t, style):
    """Squat: bend hips and knees with the heels down, arms forward, then stand up."""
    depth = keyframes(t / (2.2 / style.speed) + style.phase, (0, 0.1, 0.5, 0.6, 1.0),
                      (0, 0, 1, 1, 0)) * min(style.amplitude, 1.0)
    for side in ("left", "right"):
        body.leg(side, hip_flex=deg(95) * depth, knee_flex=deg(125) * depth,
                 hip_abduct=deg(8))
        body.arm(side, shoulder_flex=deg(85) * depth, elbow_flex=deg(10))
    body.trunk(lean=deg(35) * depth)


def kick(body, t, style):
    """Kick: swing one leg back, snap it forward straight, bring it back down."""
    phase = t / (1.7 / style.speed) + style.phase
    knots = (0.0, 0.2, 0.4, 0.55, 0.75, 1.0)
    swing = keyframes(phase, knots, deg((0, 0, -20, 85, 20, 0))) * style.amplitude
    body.leg(style.side, hip_flex=swing, knee_flex=keyframes(phase, knots, deg((5, 5, 70, 5, 60, 5))))
    body.leg(style.other, knee_flex=deg(8))
    body.trunk(lean=keyframes(phase, knots, deg((0, 0, 5, -15, 0, 0))))
    for side in ("left", "right"):
        body.arm(side, shoulder_abduct=deg(25), elbow_flex=deg(30))


def throw(body, t, style):
    """Throw overhand: step, cock the arm behind the head, whip it forward and down."""
    phase = t / (2.0 / style.speed) + style.phase
    knots = (0.0, 0.15, 0.45, 0.55, 0.7, 1.0)
    turn = SIDES[style.side][1]  # a right-hander turns right (negative yaw) to wind up
    body.arm(style.side,
             shoulder_flex=keyframes(phase, knots, deg((0, 0, 200, 120, 30, 0))) * style.amplitude,
             elbow_flex=keyframes(phase, knots, deg((10, 10, 100, 20, 10, 10))),
             shoulder_abduct=keyframes(phase, knots, deg((5, 5, 30, 10, 5, 5))))
    body.arm(style.other, shoulder_flex=keyframes(phase, knots, deg((0, 0, 80, 20, -20, 0))),
             elbow_flex=deg(20))
    body.trunk(lean=keyframes(phase, knots, deg((0, 0, -10, 20, 25, 0))),
               twist=keyframes(phase, knots, deg((0, 0, 30, -25, -30, 0))) * turn)
    stride = keyframes(phase, knots, (0, 0, 1, 1, 1, 0))
    body.leg(style.other, hip_flex=deg(25) * stride, knee_flex=deg(15) * stride)
    body.leg(style.side, hip_flex=-deg(12) * stride, knee_flex=deg(5))


def sit_down(body, t, style):
    """Sit down: stand, lean forward while bending hips and knees, settle upright."""
    start = 0.6 + 0.6 * style.phase
    duration = 1.6 / style.speed
    down = ramp(t, start, duration)
    lean = np.sin(np.pi * np.clip((t - start) / duration, 0.0, 1.0))
    for side in ("left", "right"):
        body.leg(side, hip_flex=deg(90) * down, knee_flex=deg(92) * down, hip_abduct=deg(6) * down)
        body.arm(side, shoulder_flex=deg(35) * lean + deg(20) * down,
                 elbow_flex=deg(50) * down + deg(10))
    body.trunk(lean=deg(35) * lean * style.amplitude + deg(5) * down)


ACTION_CURVES = {
    "walk": walk, "run": run, "jump": jump, "wave": wave,
    "squat": squat, "kick": kick, "throw": throw, "sit_down": sit_down,
}


def rotations(angles: np.ndarray) -> np.ndarray:
    """Turn (T, 3) roll/pitch/yaw angles into (T, 3, 3) matrices ``Rz @ Ry @ Rx``."""
    roll, pitch, yaw = angles[:, 0], angles[:, 1], angles[:, 2]
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        np.stack([-sp, cp * sr, cp * cr], -1),
    ], -2)


def forward_kinematics(body: Body, offsets: np.ndarray, heading: float) -> np.ndarray:
    """Return joint positions (T, J, 3) relative to the root, for a body facing ``heading``."""
    frames = len(body.lift)
    positions = np.zeros((frames, H36M17.n_joints, 3))
    frames_of = []
    for joint, parent in enumerate(H36M17.parents):
        local = rotations(body.angles[H36M17.joint_names[joint]])
        if parent < 0:
            frames_of.append(rotations(np.array([[0.0, 0.0, heading]])) @ local)
            continue
        positions[:, joint] = positions[:, parent] + frames_of[parent] @ offsets[joint]
        frames_of.append(frames_of[parent] @ local)
    return positions


def place_on_ground(relative: np.ndarray, body: Body) -> np.ndarray:
    """Move the root so the lower foot touches z = 0 and the stance foot does not slide.

    In flight (``lift > 0`` or stance ``"air"``) the body keeps the horizontal velocity
    it took off with.
    """
    feet = {"right": H36M17.index("RFoot"), "left": H36M17.index("LFoot")}
    foot_z = relative[:, list(feet.values()), 2]
    root = np.zeros((len(body.lift), 3))
    root[:, 2] = -foot_z.min(axis=1) + body.lift
    velocity = np.zeros(2)
    for t in range(1, len(body.lift)):
        # In the air, and on the frame of landing, keep the take-off velocity.
        airborne = body.lift[t] > 1e-4 or "air" in (body.stance[t], body.stance[t - 1])
        if not airborne:
            side = body.stance[t] or ("right" if foot_z[t, 0] <= foot_z[t, 1] else "left")
            velocity = relative[t - 1, feet[side], :2] - relative[t, feet[side], :2]
        root[t, :2] = root[t - 1, :2] + velocity
    return relative + root[:, None, :]


def make_take(action: str, rng: np.random.Generator, frames: int) -> tuple[np.ndarray, dict]:
    """Return the joints (T, 17, 3) of one synthetic take of ``action``, and its style."""
    style = Style(
        speed=rng.uniform(0.8, 1.2),
        amplitude=rng.uniform(0.8, 1.2),
        phase=rng.uniform(0.0, 1.0),
        arm_phase=rng.uniform(-0.3, 0.3),
        side=str(rng.choice(["left", "right"])),
    )
    scale = rng.uniform(0.85, 1.15)
    heading = rng.uniform(-np.pi / 4, np.pi / 4)
    start = np.append(rng.uniform(-0.5, 0.5, size=2), 0.0)
    offsets = np.array([REST_OFFSETS[name] for name in H36M17.joint_names]) * scale
    body = Body(frames)
    ACTION_CURVES[action](body, np.arange(frames) / FPS, style)
    joints = place_on_ground(forward_kinematics(body, offsets, heading), body) + start
    info = {"scale": round(float(scale), 3), "speed": round(float(style.speed), 3),
            "amplitude": round(float(style.amplitude), 3), "side": style.side}
    return joints, info


@lru_cache(maxsize=4)
def generate(seed: int = 0, takes_per_action: int = 24, seconds: float = 4.0) -> tuple[Motion, ...]:
    """Return every synthetic take, deterministic for a seed (cached in memory)."""
    frames = int(round(seconds * FPS))
    motions = []
    for action_index, action in enumerate(ACTIONS):
        for number in range(takes_per_action):
            # One generator per take: a take does not depend on how many others are made.
            rng = np.random.default_rng([seed, action_index, number])
            joints, info = make_take(action, rng, frames)
            motion = Motion(joints, "h36m17", FPS, action, meta={
                "dataset": "demo", "subject": None, "take": f"{action}_{number:02d}",
                "synthetic": True, "seed": seed, **info,
            })
            motion.joints.flags.writeable = False  # shared by every caller of the cache
            motions.append(motion)
    return tuple(motions)


@register_dataset("demo")
class Demo(Dataset):
    """SYNTHETIC procedural motions of 8 actions (not motion capture), built in."""

    skeleton = "h36m17"
    fps = FPS
    clip_frames = 60
    clip_fps = 25.0
    subjects = None
    synthetic = True

    seed = 0
    takes_per_action = 24
    seconds = 4.0

    def actions(self) -> list[str]:
        """Return the 8 synthetic actions."""
        return list(ACTIONS)

    def load_takes(self, subjects=None, actions=None) -> LoadReport:
        """Return the synthetic takes of the requested actions."""
        self.check_subjects(subjects)
        wanted = set(self.check_actions(actions))
        takes = generate(self.seed, self.takes_per_action, self.seconds)
        # Copies, so callers may change joints in place without touching the cache.
        return LoadReport(motions=[
            take.with_joints(take.joints.copy(), meta=dict(take.meta))
            for take in takes if take.action in wanted
        ])
