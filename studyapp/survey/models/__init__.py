"""The data model of studies, one module per concern; every model keeps the ``survey`` app
label, so databases made before the split migrate forward unchanged.

- :mod:`.study`: ``Study`` (type, options, texts, places, crowd, duration);
- :mod:`.stimuli`: ``Stimulus`` (a registered clip and its role), ``ScoringStandard``;
- :mod:`.participation`: ``Participant``, ``Trial``, ``TrialItem`` (answers, fetches),
  ``Balance`` (the balanced planner's kept counts);
- :mod:`.jobs`: ``BuildJob``; :mod:`.logins`: ``FailedLogin``;
- :mod:`.rows`: no models: the answer path's statements written out from the models'
  metadata, read and written with the ORM's conversions.

The lower modules never import the higher: participation imports stimuli and study,
stimuli imports study; where a study counts its participants it asks Django's app
registry for the model (:func:`.study.model`) instead of importing it back.
"""

from studyapp.survey.models.study import Study, Unavailable, new_token, study_type_choices
from studyapp.survey.models.stimuli import ScoringStandard, Stimulus
from studyapp.survey.models.participation import (
    Balance, BalanceCount, Participant, Response, Trial, TrialItem,
)
from studyapp.survey.models.jobs import BuildJob
from studyapp.survey.models.logins import FailedLogin

__all__ = [
    "Balance", "BalanceCount", "BuildJob", "FailedLogin", "Participant", "Response",
    "ScoringStandard", "Stimulus", "Study", "Trial", "TrialItem", "Unavailable", "new_token",
    "study_type_choices",
]
