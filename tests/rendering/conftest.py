"""Factories for rendering tests: a plausible walking figure of any 3D skeleton."""

import numpy as np

from motion.motion import Motion
from motion.skeletons import get_skeleton

# Joints in a body frame (towards the figure's left, up, forward), metres, standing.
_BODY = {
    "hip": (0.0, 0.95, 0.0), "spine": (0.0, 1.18, 0.0), "chest": (0.0, 1.30, 0.0),
    "thorax": (0.0, 1.42, 0.0),
    "neck": (0.0, 1.50, 0.02), "head": (0.0, 1.62, 0.0),
    "l_hip": (0.12, 0.93, 0.0), "l_knee": (0.12, 0.50, 0.02), "l_ankle": (0.12, 0.08, 0.0),
    "l_foot": (0.12, 0.02, 0.12), "l_collar": (0.07, 1.45, 0.0), "l_shoulder": (0.18, 1.40, 0.0),
    "l_elbow": (0.21, 1.12, 0.0), "l_wrist": (0.23, 0.86, 0.02), "l_hand": (0.23, 0.78, 0.03),
}
_H36M = ["hip", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle", "spine", "thorax",
         "neck", "head", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist"]
_SMPL = ["hip", "l_hip", "r_hip", "spine", "l_knee", "r_knee", "chest", "l_ankle", "r_ankle",
         "thorax", "l_foot", "r_foot", "neck", "l_collar", "r_collar", "head", "l_shoulder",
         "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_hand", "r_hand"]
_LAYOUTS = {"h36m17": _H36M, "humanact12": _SMPL}
_SWING = {"knee": 0.12, "ankle": 0.25, "foot": 0.25, "elbow": -0.08, "wrist": -0.18, "hand": -0.2}


def _joint(name: str, phase: float) -> np.ndarray:
    side = name[:2] if name[:2] in ("l_", "r_") else ""
    left, up, forward = _BODY[name.replace("r_", "l_")]
    if side == "r_":
        left = -left
    swing = _SWING.get(name.split("_")[-1], 0.0) * np.sin(phase + (np.pi if side == "r_" else 0.0))
    return np.array([left, up, forward + swing])


def make_figure(
    skeleton="h36m17", frames=12, speed=0.0, fps=25.0, action="walk", source="real", phase=0.0
):
    """Return a figure swinging its limbs and moving forward ``speed`` metres a second."""
    layout = _LAYOUTS[skeleton]
    poses = []
    for t in range(frames):
        angle = phase + 2 * np.pi * t / fps
        body = np.stack([_joint(name, angle) for name in layout])
        body[:, 2] += speed * t / fps
        poses.append(body)
    body = np.array(poses)
    left, up, forward = body[..., 0], body[..., 1], body[..., 2]
    if get_skeleton(skeleton).up == "z":  # facing -y with z up
        joints = np.stack([left, -forward, up], axis=-1)
    else:  # facing +z with y up
        joints = np.stack([left, up, forward], axis=-1)
    return Motion(joints, skeleton, fps, action, source)


def drifting_walk(frames=50, fps=25.0, at=1.0, source="cond_gru"):
    """A walk that side-steps 2.4 m to the camera's right within 0.16 s from ``at``
    seconds, as a generated walk may (the rule's azimuth of -50 degrees: along (0.77,
    0.64)); the camera, smoothed over a second, lags behind it."""
    walk = make_figure(frames=frames, speed=1.3, fps=fps, source=source)
    t = np.arange(frames) / fps
    step = 2.4 * np.clip((t - at) / 0.16, 0.0, 1.0)[:, None]
    joints = walk.joints.copy()
    joints[..., 0] += 0.77 * step
    joints[..., 1] += 0.64 * step
    return walk.with_joints(joints.astype(np.float32))


def rising_figure(frames=50, fps=25.0, at=0.6, source="broken", action="walk", phase=1.0):
    """A figure broken upwards: from ``at`` seconds it floats higher and higher."""
    base = make_figure(frames=frames, speed=1.0, fps=fps, action=action, phase=phase)
    t = np.arange(frames) / fps
    joints = base.joints.copy()
    joints[..., 2] += (1.2 * np.maximum(0.0, t - at) ** 2 * (50 / frames) ** 2)[:, None]
    return base.with_joints(joints.astype(np.float32), source=source)


def shaken_anchor(frames=50, fps=25.0, seed=3, action="walk"):
    """A low anchor (:func:`motion.perturb.low_anchor`) of a walking figure."""
    from motion import perturb

    base = make_figure(frames=frames, speed=1.0, fps=fps, action=action, phase=2.0)
    return perturb.low_anchor(base, np.random.default_rng(seed))
