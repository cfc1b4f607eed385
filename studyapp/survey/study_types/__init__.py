"""Study types: every protocol's plug-in (see :mod:`.base`).

Each type is one module here that subclasses :class:`StudyType` and registers itself with
``@register_study_type("key")``, with its template beside it (``<key>.html``) and its
analysis in ``analysis/``. ``get_study_type``, ``list_study_types`` and ``choices`` read
the registry, which imports every module of this folder before its first lookup, so a new
type needs no list.
"""

from pathlib import Path

from studyapp.survey.study_types.base import StudyType, TrialPlan, registry

register_study_type = registry.register
FOLDER = Path(__file__).resolve().parent


def get_study_type(name: str) -> StudyType:
    """Return an instance of the study type class registered as ``name``."""
    return registry.get(name)()


def list_study_types() -> list[str]:
    return registry.names()


def choices() -> list[tuple[str, str]]:
    return [(name, registry.get(name).label) for name in registry.names()]

__all__ = [
    "FOLDER",
    "StudyType",
    "TrialPlan",
    "choices",
    "get_study_type",
    "list_study_types",
    "register_study_type",
]
