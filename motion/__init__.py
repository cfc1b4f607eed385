"""Human motion as plain numpy: the data model every layer shares, and how it comes in.

This package never imports Django or another layer of the project (torch only inside the
body models' functions, where ``smplx`` needs it). Its pieces:

- :class:`motion.motion.Motion`, the one motion type every layer shares;
- :mod:`motion.skeletons`, named skeletons as data, and :mod:`motion.ops`, free functions
  on motions (canonical axes, units, resampling);
- :mod:`motion.datasets`, a registry of real datasets (``demo``, ``h36m``, ``h36m2d``,
  ``humanact12``, ``humanml3d``, ...);
- :mod:`motion.formats`, a registry of other codebases' files (``load``/``save`` per
  format, ``npz`` the interchange file), read through :mod:`motion.safe_load`;
- :mod:`motion.perturb`, broken versions of motions (catch clips, anchors);
- :mod:`motion.registry`, the one ``Registry`` every registry of the project uses.
"""

from motion.motion import Motion, MotionError

__all__ = ["Motion", "MotionError"]
