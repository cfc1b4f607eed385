"""The ``h36m`` dataset: Human3.6M 3D joint positions, 17 joints, metres, z up, 25 fps.

Two layouts of the data root are read:

- compact: ``h36m_positions_25fps.npz``, one ``(frames, 17, 3)`` float array in metres at
  25 fps per take, keyed ``S1/Walking 1`` (``index.json`` beside it is not needed);
- original (3d-pose-baseline): ``S*/MyPoses/3D_positions/<take>.h5``, dataset
  ``3D_positions`` of shape ``(96, frames)``: 32 joints in millimetres at 50 Hz; the 17
  joints of ``h36m17`` are kept and every 2nd frame.
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion.datasets.base import Dataset, DatasetError, LoadReport, register_dataset
from motion.motion import Motion
from motion.skeletons import H36M32_TO_17

COMPACT_FILE = "h36m_positions_25fps.npz"
H5_PATTERN = "S*/MyPoses/3D_positions/*.h5"
H5_DATASET = "3D_positions"
SUBJECTS = ("S1", "S5", "S6", "S7", "S8", "S9", "S11")
ACTIONS = ("Directions", "Discussion", "Eating", "Greeting", "Phoning", "Photo", "Posing",
           "Purchases", "Sitting", "SittingDown", "Smoking", "Waiting", "WalkDog",
           "WalkTogether", "Walking")
# Names some copies of Human3.6M use for the same actions.
ALIASES = {"TakingPhoto": "Photo", "WalkingDog": "WalkDog"}

LAYOUTS = (
    f"either {COMPACT_FILE} (arrays (frames, 17, 3) in metres at 25 fps, keyed "
    f"'S1/Walking 1') or the 3d-pose-baseline layout {H5_PATTERN} (dataset "
    f"{H5_DATASET!r} of shape (96, frames): 32 joints in millimetres at 50 Hz)"
)
H5_LAYOUT = f"an HDF5 file with dataset {H5_DATASET!r} of shape (96, frames) in millimetres"


def action_of(take: str) -> str:
    """Return the action of a take name: ``"Walking 1"`` -> ``"Walking"``.

    Only a trailing take number is dropped, so ``WalkDog``, ``WalkTogether`` and
    ``SittingDown`` stay actions of their own.
    """
    name = re.sub(r"\s+\d+$", "", take.strip())
    return ALIASES.get(name, name)


@dataclass(frozen=True)
class Take:
    """Where one take lives: ``key`` in the compact file, or ``path`` of its .h5 file."""

    subject: str
    take: str
    action: str
    key: str = ""
    path: Path | None = None


@register_dataset("h36m")
class H36M(Dataset):
    """Human3.6M 3D joint positions (Hip-rooted 17 joints), metres, z up, 25 fps."""

    skeleton = "h36m17"
    fps = 25.0
    clip_frames = 60
    clip_fps = 25.0
    subjects = SUBJECTS
    env_var = "STUDY_H36M_ROOT"
    default_dir = "../shared/data/h36m"

    def __init__(self, data_root=None):
        super().__init__(data_root)
        self._takes: list[Take] | None = None
        self._arrays: dict[Take, np.ndarray] = {}  # loaded takes, kept for later calls

    def actions(self) -> list[str]:
        """Return the 15 Human3.6M actions."""
        return list(ACTIONS)

    def known_actions(self) -> list[str]:
        """Return the 15 Human3.6M actions (subclasses may default to fewer)."""
        return list(ACTIONS)

    @property
    def compact_file(self) -> Path:
        """Return where the compact file would be."""
        return Path(self.data_root) / COMPACT_FILE

    def takes(self, subjects=None, actions=None) -> list[Take]:
        """Return the takes found under the root, filtered, in subject then name order."""
        if self._takes is None:
            self._takes = self._find_takes()
        subjects = self.check_subjects(subjects)
        actions = set(self.check_actions(actions))
        return [take for take in self._takes
                if (subjects is None or take.subject in subjects) and take.action in actions]

    def _find_takes(self) -> list[Take]:
        """List the takes of the compact file, else of the original layout."""
        root = self.data_root
        fix = f"set {self.env_var} or pass --data-root DIR"
        if root is None or not Path(root).is_dir():
            raise DatasetError(f"Human3.6M folder {root} not found; it should hold {LAYOUTS}; "
                               f"{fix}")
        if self.compact_file.is_file():
            try:
                with zipfile.ZipFile(self.compact_file) as archive:
                    keys = [name[:-4] for name in archive.namelist() if name.endswith(".npy")]
            except (OSError, zipfile.BadZipFile) as exc:
                raise DatasetError(
                    f"{self.compact_file} is not a readable .npz file ({exc}); expected {LAYOUTS}"
                ) from exc
            takes = []
            for key in keys:
                subject, _, take = key.partition("/")
                if take:
                    takes.append(Take(subject, take, action_of(take), key=key))
        else:
            takes = [Take(path.parts[-4], path.stem, action_of(path.stem), path=path)
                     for path in Path(root).glob(H5_PATTERN)]
        if not takes:
            found = sorted(p.name for p in Path(root).iterdir())[:10]
            raise DatasetError(
                f"no Human3.6M takes in {root} (found: {', '.join(found) or 'nothing'}); "
                f"it should hold {LAYOUTS}; {fix}"
            )
        order = {subject: i for i, subject in enumerate(SUBJECTS)}
        return sorted(takes, key=lambda t: (order.get(t.subject, len(order)), t.subject, t.take))

    def load_takes(self, subjects=None, actions=None) -> LoadReport:
        """Return whole takes (17 joints, metres, 25 fps) and one line per unreadable take."""
        report = LoadReport()
        takes = self.takes(subjects, actions)
        for subject in self.check_subjects(subjects) or []:
            if not any(take.subject == subject for take in takes):
                report.problems.append(f"{self.data_root}: no takes of subject {subject}")
        if actions is None:
            wanted = self.check_subjects(subjects)
            report.problems.extend(
                f"{take.path or self.compact_file}: take {take.take!r} of {take.subject} is "
                f"none of the actions {', '.join(ACTIONS)}; skipped"
                for take in self._takes
                if take.action not in ACTIONS and (wanted is None or take.subject in wanted)
            )
        npz = None
        try:
            for take in takes:
                try:
                    if take not in self._arrays:
                        if take.path is not None:
                            self._arrays[take] = read_h5(take.path)
                        else:
                            npz = npz if npz is not None else np.load(self.compact_file)
                            self._arrays[take] = read_compact(npz, take.key, self.compact_file)
                except DatasetError as exc:
                    report.problems.append(str(exc))
                    continue
                report.motions.append(self._motion(take, self._arrays[take]))
        finally:
            if npz is not None:
                npz.close()
        return report

    def _motion(self, take: Take, joints: np.ndarray) -> Motion:
        meta = {"dataset": self.name, "subject": take.subject, "take": take.take}
        return Motion(joints, "h36m17", self.fps, take.action, meta=meta)

    def take_lengths(self, subjects=None, actions=None) -> list[int]:
        """Return each take's frames at 25 fps, from the file headers (no joint data read)."""
        lengths = []
        takes = self.takes(subjects, actions)
        if any(take.path is None for take in takes):
            with zipfile.ZipFile(self.compact_file) as archive:
                for take in takes:
                    try:
                        with archive.open(take.key + ".npy") as handle:
                            version = np.lib.format.read_magic(handle)
                            header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                                      else np.lib.format.read_array_header_2_0)(handle)
                    except Exception:  # a damaged member; load_takes reports it
                        continue
                    shape = header[0]
                    if len(shape) == 3 and shape[1:] == (17, 3):
                        lengths.append(shape[0])
            return lengths
        import h5py  # only the original layout needs it (and it is slow to import)

        for take in takes:
            try:
                with h5py.File(take.path, "r") as handle:
                    shape = handle[H5_DATASET].shape
            except (OSError, KeyError):
                continue  # load_takes reports it
            if len(shape) == 2 and shape[0] == 96:
                lengths.append((shape[1] + 1) // 2)  # every 2nd of the 50 Hz frames
        return lengths


def read_compact(npz, key: str, path: Path) -> np.ndarray:
    """Return one take of the compact file as (frames, 17, 3) metres, or raise DatasetError."""
    try:
        joints = npz[key]
    except Exception as exc:  # zlib and zipfile raise several types for a damaged member
        raise DatasetError(f"{path}: take {key!r} is unreadable ({exc})") from exc
    if joints.ndim != 3 or joints.shape[1:] != (17, 3) or len(joints) == 0:
        raise DatasetError(
            f"{path}: take {key!r} has shape {joints.shape}; expected (frames, 17, 3) in metres"
        )
    if not np.isfinite(joints).all():
        raise DatasetError(f"{path}: take {key!r} has non-finite joint coordinates")
    return joints.astype(np.float32)


def read_h5(path: Path) -> np.ndarray:
    """Return one take of the original layout as (frames, 17, 3) metres at 25 fps."""
    import h5py  # only the original layout needs it (and it is slow to import)

    try:
        with h5py.File(path, "r") as handle:
            if H5_DATASET not in handle:
                raise DatasetError(
                    f"{path}: no dataset {H5_DATASET!r} (found: {', '.join(handle) or 'nothing'}); "
                    f"expected {H5_LAYOUT}"
                )
            data = np.asarray(handle[H5_DATASET][()])
    except OSError as exc:
        raise DatasetError(
            f"{path}: not a readable HDF5 file ({exc}); expected {H5_LAYOUT}"
        ) from exc
    if data.ndim != 2 or data.shape[0] != 96 or data.shape[1] == 0:
        raise DatasetError(f"{path}: {H5_DATASET!r} has shape {data.shape}; expected {H5_LAYOUT}")
    if not np.isfinite(data).all():
        raise DatasetError(f"{path}: {H5_DATASET!r} has non-finite values")
    joints = data.T.reshape(-1, 32, 3)[:, list(H36M32_TO_17)] / 1000.0  # mm -> metres
    return joints[::2].astype(np.float32)  # 50 Hz -> 25 fps
