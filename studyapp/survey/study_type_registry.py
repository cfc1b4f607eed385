"""The registry of study types, below the models.

The types (``studyapp/survey/study_types/``) build on the models, and the models ask
for a study's type (``Study.kind``, the choices of ``Study.study_type``): both import
this registry, which finds the types' modules by name on its first lookup, so neither
imports the other's module in a circle.
"""

from motion.registry import Registry

STUDY_TYPES = Registry("study type", package="studyapp.survey.study_types")
