"""Motions of every method of the seed papers, and real data, as plain numpy.

This package never imports Django. Its public pieces:

- :class:`generation.motion.Motion`, the one motion type every layer shares;
- :mod:`generation.skeletons`, named skeletons as data;
- :mod:`generation.datasets`, a registry of datasets (``demo``, ``h36m``, ``h36m2d``,
  ``humanact12``);
- :mod:`generation.methods`, a registry of generative methods;
- :mod:`generation.formats.npz`, the interchange file for sets of motions.
"""

from generation.motion import Motion, MotionError

__all__ = ["Motion", "MotionError"]
