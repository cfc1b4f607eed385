"""The ``h36m2d`` dataset: Human3.6M in 2D, as in seeds 003/004.

The ``h36m`` takes, projected onto camera ``55011271`` of their subject (pixels, y down),
keeping the 15 joints of ``h36m15_2d`` (Hip and Neck/Nose dropped). The papers sample
50 Hz data every 3rd frame (16.7 Hz); our takes are 50 Hz every 2nd frame, so clips are
resampled from 25 to 50/3 fps by default. Default actions: the papers' 10 classes.
"""

from __future__ import annotations

from motion.datasets.base import LoadReport, register_dataset
from motion.datasets.cameras import load_cameras
from motion.datasets.h36m import H36M
from motion.skeletons import H36M15_2D_FROM_17

CAMERA = "55011271"
CLASSES = ("Directions", "Discussion", "Eating", "Greeting", "Phoning", "Posing", "Sitting",
           "SittingDown", "Smoking", "Walking")


@register_dataset("h36m2d")
class H36M2D(H36M):
    """Human3.6M projected onto camera 55011271: 15 joints in pixels, y down."""

    skeleton = "h36m15_2d"
    clip_frames = 50
    clip_fps = 50 / 3
    camera = CAMERA

    def __init__(self, data_root=None):
        super().__init__(data_root)
        self._cameras = None

    def actions(self) -> list[str]:
        """Return the 10 classes of seeds 003/004 (any of the 15 may be asked for)."""
        return list(CLASSES)

    def cameras(self) -> dict:
        """Return ``{subject: {name: Camera}}`` from the root's camera file."""
        self.takes()  # a missing folder is the first thing to report
        if self._cameras is None:
            self._cameras = load_cameras(self.data_root)
        return self._cameras

    def take_lengths(self, subjects=None, actions=None) -> list[int]:
        self.cameras()  # no clips without cameras
        return super().take_lengths(subjects, actions)

    def load_takes(self, subjects=None, actions=None) -> LoadReport:
        """Return whole projected takes at 25 fps, and the problems met."""
        cameras = self.cameras()
        report = super().load_takes(subjects, actions)
        projected = []
        for take in report.motions:
            camera = cameras.get(take.meta["subject"], {}).get(self.camera)
            if camera is None:
                report.problems.append(
                    f"{self.data_root}: no camera {self.camera} for subject "
                    f"{take.meta['subject']}; take {take.meta['take']!r} skipped"
                )
                continue
            pixels = camera.project(take.joints * 1000.0)  # metres -> millimetres
            projected.append(take.with_joints(
                pixels[:, list(H36M15_2D_FROM_17)], skeleton="h36m15_2d",
                meta={**take.meta, "camera": self.camera},
            ))
        report.motions = projected
        return report
