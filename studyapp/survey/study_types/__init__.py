"""Study types: what a trial shows, how its answer is checked and stored.

Each type is one module that subclasses :class:`StudyType` and registers itself with
``@register_study_type("key")``; the participant flow, assignment locking and clip
serving are shared. ``get_study_type``, ``list_study_types`` and ``choices`` read the
registry.
"""

from studyapp.survey.study_types.base import StudyType, TrialPlan, registry

register_study_type = registry.register


def get_study_type(name: str) -> StudyType:
    """Return the registered study type ``name`` (an instance)."""
    return registry.get(name)()


def list_study_types() -> list[str]:
    return registry.names()


def choices() -> list[tuple[str, str]]:
    return [(name, registry.get(name).label) for name in registry.names()]


# Built-in types register on import.
from studyapp.survey.study_types import (  # noqa: E402, F401
    fake_or_real,
    pairwise,
    ranking,
    rating_reference,
    rating_standards,
)

__all__ = [
    "StudyType",
    "TrialPlan",
    "choices",
    "get_study_type",
    "list_study_types",
    "register_study_type",
]
