"""The one motion type shared by every layer."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace

import numpy as np

from motion.skeletons import get_skeleton, is_custom, register_custom

UNKNOWN_ACTION = "unknown"  # the action of motions that came with none (e.g. text prompts)


class MotionError(ValueError):
    """A motion is malformed (wrong shape, wrong skeleton, non-finite joints)."""


@dataclass(frozen=True, eq=False)
class Motion:
    """A joint trajectory of one skeleton.

    ``joints`` has shape ``(T, J, D)`` with ``D`` 3 (metres, the skeleton's up axis)
    or 2 (image coordinates). ``source`` is ``"real"`` for data, else a method key.
    ``meta`` carries provenance (subject, take, start frame, ...). ``text`` is the prompt
    the motion was generated from, or a real clip's caption (``None``: none).
    ``vertices`` ``(T, V, 3)`` is the body surface when an import carried one (same axes
    and units as the joints), with its triangles ``faces`` ``(F, 3)``.
    """

    joints: np.ndarray
    skeleton: str
    fps: float
    action: str
    source: str = "real"
    meta: dict = field(default_factory=dict)
    text: str | None = None
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None

    def __post_init__(self):
        joints = np.asarray(self.joints, dtype=np.float32)
        object.__setattr__(self, "joints", joints)
        skeleton = get_skeleton(self.skeleton)
        if joints.ndim != 3:
            raise MotionError(
                f"joints must have shape (T, J, D); got {joints.shape} "
                f"for a {self.skeleton!r} motion of action {self.action!r}"
            )
        frames, n_joints, dims = joints.shape
        if n_joints != skeleton.n_joints or dims != skeleton.dims:
            raise MotionError(
                f"joints of shape {joints.shape} do not fit skeleton {skeleton.name!r}, "
                f"which has {skeleton.n_joints} joints in {skeleton.dims}D; "
                f"pass the skeleton the data was recorded with"
            )
        if not self.fps or self.fps <= 0:
            raise MotionError(f"fps must be positive; got {self.fps!r}")
        if self.text is not None:
            object.__setattr__(self, "text", str(self.text))
        self._check_body(frames)

    def _check_body(self, frames: int) -> None:
        """Check (and store as float32/int64) the vertices and faces, if any."""
        if self.vertices is None:
            if self.faces is not None:
                raise MotionError("faces without vertices; pass both or neither")
            return
        vertices = np.asarray(self.vertices, dtype=np.float32)
        if vertices.ndim != 3 or vertices.shape[0] != frames or vertices.shape[2] != 3:
            raise MotionError(f"vertices must have shape (T={frames}, V, 3); got "
                              f"{vertices.shape}")
        if self.faces is None:
            raise MotionError("vertices without faces; pass the body's triangles (F, 3)")
        faces = np.asarray(self.faces)
        if (faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer)
                or (faces < 0).any() or (faces >= vertices.shape[1]).any()):
            raise MotionError(f"faces must be (F, 3) vertex indices below {vertices.shape[1]}; "
                              f"got {faces.dtype} of shape {faces.shape}")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces.astype(np.int64))

    def __getstate__(self):
        state = dict(self.__dict__)
        if is_custom(self.skeleton):  # a spawned process has only the built-in skeletons
            state["_skeleton_definition"] = get_skeleton(self.skeleton)
        return state

    def __setstate__(self, state):
        state = dict(state)
        definition = state.pop("_skeleton_definition", None)
        if definition is not None:
            register_custom(definition)
        for key, value in state.items():
            object.__setattr__(self, key, value)

    @property
    def frames(self) -> int:
        return self.joints.shape[0]

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.frames / self.fps

    @property
    def has_body(self) -> bool:
        """Return whether the motion carries its own body surface."""
        return self.vertices is not None

    def with_joints(self, joints: np.ndarray, **changes) -> "Motion":
        """Return a copy with other joints (and any other field changed).

        A motion with vertices keeps them only for joints of the same length; other
        lengths need ``vertices`` too (``motion.ops.resample``/``trim`` pass them).
        """
        if (self.vertices is not None and "vertices" not in changes
                and len(joints) != self.frames):
            raise MotionError(
                f"this motion carries a body surface of {self.frames} frames; new joints of "
                f"{len(joints)} frames need their vertices too (use motion.ops.resample "
                "or motion.ops.trim)"
            )
        return replace(self, joints=joints, **changes)

    def check_finite(self) -> None:
        """Raise :class:`MotionError` if any joint coordinate is NaN or infinite."""
        bad = ~np.isfinite(self.joints)
        if bad.any():
            frame = int(np.argwhere(bad)[0][0])
            raise MotionError(
                f"motion {self.action!r} from {self.source!r} has {int(bad.sum())} "
                f"non-finite joint coordinates (first at frame {frame}); "
                f"drop or repair that motion"
            )

    def content_hash(self) -> str:
        """Return a hash of what a clip shows: joints, skeleton and body (not the source)."""
        digest = hashlib.sha256()
        digest.update(self.skeleton.encode())
        digest.update(np.float32(self.fps).tobytes())
        digest.update(np.ascontiguousarray(self.joints).tobytes())
        if self.vertices is not None:
            digest.update(np.ascontiguousarray(self.vertices).tobytes())
            digest.update(np.ascontiguousarray(self.faces).tobytes())
        return digest.hexdigest()[:16]
