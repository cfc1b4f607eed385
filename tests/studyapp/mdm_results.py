"""MDM's ``results.npy`` written as ``sample/generate.py`` writes it, for tests of prompts
studies: ``np.save`` of a dict with ``motion`` ``(N, 22, 3, T)``, ``text`` (N prompts),
``lengths``, ``num_samples`` and ``num_repetitions``; motion ``rep * num_samples + k`` is
repetition ``rep`` of prompt ``k``; 20 fps."""

import numpy as np

from tests.motion.body_model_files import rest_joints


def moving_body(frames: int, seed: int) -> np.ndarray:
    """Return joints ``(T, 22, 3)``, y up, metres: SMPL's rest pose stepping forward with
    swinging arms, different for every seed."""
    rng = np.random.default_rng(seed)
    body = rest_joints(24)[:22]
    t = np.arange(frames)[:, None]
    joints = np.repeat(body[None], frames, axis=0).astype(np.float64)
    speed, swing, phase = rng.uniform(0.005, 0.03), rng.uniform(0.05, 0.25), rng.uniform(0, 6)
    joints[:, :, 2] += speed * t  # forward
    wave = np.sin(0.4 * t[:, 0] + phase)
    for wrist, sign in ((20, 1), (21, -1), (18, 1), (19, -1)):  # wrists and elbows
        joints[:, wrist, 2] += sign * swing * wave * (1.0 if wrist >= 20 else 0.5)
    for ankle, sign in ((7, 1), (8, -1), (10, 1), (11, -1)):  # ankles and feet
        joints[:, ankle, 2] += sign * 0.6 * swing * wave
    return (joints + rng.normal(scale=0.003, size=joints.shape)).astype(np.float32)


def write_mdm_results(path, prompts, repetitions=2, frames=40, lengths=None, seed=0):
    """Write a results.npy of ``len(prompts) * repetitions`` motions; return the dict saved."""
    n = len(prompts) * repetitions
    motion = np.stack([moving_body(frames, seed * 1000 + i) for i in range(n)])
    data = {
        "motion": motion.transpose(0, 2, 3, 1),  # (N, 22, 3, T)
        "text": [prompts[i % len(prompts)] for i in range(n)],
        "lengths": np.array(lengths if lengths is not None else [frames] * n),
        "num_samples": len(prompts),
        "num_repetitions": repetitions,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, data)
    return data
