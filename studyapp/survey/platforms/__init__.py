"""Crowd platforms, one module each (see :mod:`studyapp.survey.crowd`): each registers a
:class:`~studyapp.survey.crowd.Platform` by being here."""
