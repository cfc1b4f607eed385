"""The one motion type shared by every layer."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace

import numpy as np

from generation.skeletons import get_skeleton


class MotionError(ValueError):
    """A motion is malformed (wrong shape, wrong skeleton, non-finite joints)."""


@dataclass(frozen=True, eq=False)
class Motion:
    """A joint trajectory of one skeleton.

    ``joints`` has shape ``(T, J, D)`` with ``D`` 3 (metres, the skeleton's up axis)
    or 2 (image coordinates). ``source`` is ``"real"`` for data, else a method key.
    ``meta`` carries provenance (subject, take, start frame, ...).
    """

    joints: np.ndarray
    skeleton: str
    fps: float
    action: str
    source: str = "real"
    meta: dict = field(default_factory=dict)

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

    @property
    def frames(self) -> int:
        return self.joints.shape[0]

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.frames / self.fps

    def with_joints(self, joints: np.ndarray, **changes) -> "Motion":
        """Return a copy with other joints (and any other field changed)."""
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
        """Return a hash of the joint values and skeleton (not the source)."""
        digest = hashlib.sha256()
        digest.update(self.skeleton.encode())
        digest.update(np.float32(self.fps).tobytes())
        digest.update(np.ascontiguousarray(self.joints).tobytes())
        return digest.hexdigest()[:16]
