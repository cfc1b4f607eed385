"""Run a stimulus build off the request thread (e.g. from an admin action), reporting progress.

:func:`run_build` is what a background thread calls; it opens and closes its own
database connection, as any thread that uses the ORM must.
"""

from __future__ import annotations

from django.db import close_old_connections

from studyapp.stimuli.build import build_stimuli, default_folders
from studyapp.stimuli.config import load_config


def run_build(config_path, progress_callback=None, overrides=(), folder=None):
    """Build the config at ``config_path``; call ``progress_callback(done, total, message)``.

    Return the :class:`~studyapp.stimuli.build.BuildResult`; errors propagate
    (``ConfigError``, ``BuildError``) for the caller to record.
    """
    close_old_connections()
    try:
        config = load_config(config_path, overrides)
        folder, cache = default_folders(config, folder)
        return build_stimuli(config, folder, progress=progress_callback, cache=cache)
    finally:
        close_old_connections()
