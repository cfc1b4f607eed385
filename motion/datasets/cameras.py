"""Human3.6M cameras: read their parameters and project world points to pixels."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion.datasets.base import DatasetError

CAMERAS_JSON = "cameras.json"
CAMERAS_H5 = "cameras.h5"  # the file 3d-pose-baseline ships
LAYOUT = (
    f"{CAMERAS_JSON} ({{'subjects': {{'S1': [{{'name', 'R', 'T', 'f', 'c', 'k', 'p'}}, ...]}}}}: "
    "R world-to-camera rotation, T camera centre in millimetres, f and c in pixels, k radial "
    f"and p tangential distortion) or 3d-pose-baseline's {CAMERAS_H5} "
    "(subject1/camera1/R ... with the same parameters, R transposed)"
)


@dataclass(frozen=True)
class Camera:
    """One calibrated camera: ``x_cam = R (X - T)`` with X in millimetres."""

    name: str
    R: np.ndarray  # (3, 3)
    T: np.ndarray  # (3,)
    f: np.ndarray  # (2,)
    c: np.ndarray  # (2,)
    k: np.ndarray  # (3,)
    p: np.ndarray  # (2,)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Project world points ``(..., 3)`` in millimetres to pixels ``(..., 2)``, y down.

        The distortion model is 3d-pose-baseline's ``project_point_radial``.
        """
        camera = (np.asarray(points, dtype=np.float64) - self.T) @ self.R.T
        xy = camera[..., :2] / camera[..., 2:3]
        r2 = (xy**2).sum(axis=-1)
        radial = 1 + self.k[0] * r2 + self.k[1] * r2**2 + self.k[2] * r2**3
        tangential = self.p[0] * xy[..., 1] + self.p[1] * xy[..., 0]
        distorted = (xy * (radial + tangential)[..., None]
                     + np.array([self.p[1], self.p[0]]) * r2[..., None])
        return self.f * distorted + self.c


def _camera(name, R, T, f, c, k, p) -> Camera:
    arrays = [np.asarray(v, dtype=np.float64).reshape(shape)
              for v, shape in ((R, (3, 3)), (T, (3,)), (f, (2,)), (c, (2,)), (k, (3,)), (p, (2,)))]
    return Camera(str(name), *arrays)


def load_cameras(root: str | Path) -> dict[str, dict[str, Camera]]:
    """Return ``{subject: {camera name: Camera}}`` from ``cameras.json`` or ``cameras.h5``."""
    root = Path(root)
    if (root / CAMERAS_JSON).is_file():
        return _from_json(root / CAMERAS_JSON)
    if (root / CAMERAS_H5).is_file():
        return _from_h5(root / CAMERAS_H5)
    raise DatasetError(f"no camera file in {root}; expected {LAYOUT}")


def _from_json(path: Path) -> dict[str, dict[str, Camera]]:
    try:
        subjects = json.loads(path.read_text())["subjects"]
        return {
            subject: {str(cam["name"]): _camera(cam["name"], cam["R"], cam["T"], cam["f"],
                                                cam["c"], cam["k"], cam["p"]) for cam in cams}
            for subject, cams in subjects.items()
        }
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DatasetError(f"{path} is not a camera file ({exc!r}); expected {LAYOUT}") from exc


def _from_h5(path: Path) -> dict[str, dict[str, Camera]]:
    import h5py  # only this layout needs it

    cameras: dict[str, dict[str, Camera]] = {}
    try:
        with h5py.File(path, "r") as handle:
            for group in handle:  # "subject1", "subject5", ...
                subject = "S" + group.removeprefix("subject")
                for camera in handle[group].values():
                    name = _decode_name(camera["Name"][()])
                    # 3d-pose-baseline stores R transposed (camera-to-world).
                    cameras.setdefault(subject, {})[name] = _camera(
                        name, np.asarray(camera["R"][()]).T, camera["T"][()], camera["f"][()],
                        camera["c"][()], camera["k"][()], camera["p"][()])
    except (OSError, KeyError, ValueError) as exc:
        raise DatasetError(f"{path} is not a camera file ({exc!r}); expected {LAYOUT}") from exc
    return cameras


def _decode_name(raw) -> str:
    """Return a camera name stored as character codes (3d-pose-baseline) or as a string."""
    if isinstance(raw, bytes):
        return raw.decode()
    raw = np.asarray(raw).ravel()
    if raw.dtype.kind in "iuf":
        return "".join(chr(int(code)) for code in raw)
    return "".join(item.decode() if isinstance(item, bytes) else str(item) for item in raw)
