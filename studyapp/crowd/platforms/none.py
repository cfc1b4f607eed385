"""No platform (an empty ``crowd``): ``PROLIFIC_PID`` or ``participant_label`` identify a
person when present (a link made for Prolific works unchanged), and the completion page
shows a random code and links to the study's ``completion_url``."""

from __future__ import annotations

from studyapp.crowd.platform import Platform, registry
from studyapp.crowd.platforms.prolific import session_params


@registry.register("none")
class NoPlatform(Platform):
    id_params = ("PROLIFIC_PID", "participant_label")
    extra_params = ("STUDY_ID", "SESSION_ID")

    def entry_params(self, study, person):
        return super().entry_params(study, person) + session_params(study, person)
