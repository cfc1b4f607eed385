"""Crowd platforms, one module each (see :mod:`studyapp.crowd.platform`): each registers a
:class:`~studyapp.crowd.platform.Platform` by being here."""
