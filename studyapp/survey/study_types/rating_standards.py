"""Realism rating with scoring standards (seed 003, Table 3, appendix Fig. 9).

Each trial page first shows the five scoring standards of its action, each a
description and an example clip (:class:`~studyapp.survey.models.ScoringStandard`),
so that every rater uses the same scale; then the blind clips, each scored 1-5.
"""

from studyapp.survey.models import ScoringStandard
from studyapp.survey.study_types.base import registry
from studyapp.survey.study_types.rating import RatingStudy

# Descriptions used when a researcher gives only the example clips.
DEFAULT_DESCRIPTIONS = {
    1: "Not realistic at all: the body moves in ways no person could, or barely does {action}.",
    2: "Hardly realistic: clearly wrong movement, such as jerks, sliding feet or bent limbs.",
    3: "Somewhat realistic: recognisably {action}, but stiff, shaky or unnatural in places.",
    4: "Quite realistic: natural {action} with small flaws you notice when looking closely.",
    5: "Completely realistic: indistinguishable from a real person doing {action}.",
}

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows short, silent clips of a \
figure performing it. The clips play on their own and repeat.

Every question starts with the scoring standard for its action: five example clips, one \
for each score from 1 (not realistic at all) to 5 (completely realistic), each with a \
description. Use them so that your scores mean the same as everyone else's.

Then score each of the {n} clips below the standard: how realistic does the movement \
look, as an example of the named action? Watch every clip to the end at least once; the \
submit button becomes active once every clip has played through. Choose a score with the \
buttons under each clip.

There are no right or wrong answers; we are interested in your impression."""


def default_descriptions(action: str) -> dict[int, str]:
    return {score: text.format(action=action) for score, text in DEFAULT_DESCRIPTIONS.items()}


@registry.register("rating_standards")
class RatingStandards(RatingStudy):
    label = "Realism rating with scoring standards"
    interface_words = ("real",)  # "... from a real person" in the top standard

    def default_instructions(self, study):
        return INSTRUCTIONS.format(n=study.clips_per_trial)

    def trial_context(self, trial, items):
        study = trial.participant.study
        standards = ScoringStandard.objects.for_action(study, trial.action)
        return super().trial_context(trial, items) | {"standards": standards}
