"""Realism rating with a real reference clip (seed 004, Table 5).

Participants are told the action and shown one real clip of it (a stimulus whose role is
``reference``, never rated, shown beside the judged clips), then score each clip 1-5. A
repeated trial shows the same reference again.
"""

from studyapp.survey.models import Stimulus, TrialItem
from studyapp.survey.study_types.base import registry
from studyapp.survey.study_types.rating import RatingStudy

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows short, silent clips of a \
figure performing it. The clips play on their own and repeat.

At the top of each question is a reference: a clip of a real person doing the action, \
so you know what it looks like. It is not scored.

Score each of the {n} clips below it: how realistic does the movement look, as an \
example of the named action, from 1 (not realistic at all) to 5 (completely realistic)? \
Watch the reference and every clip to the end at least once; the submit button becomes \
active once they have all played through. Choose a score with the buttons under each clip."""


@registry.register("rating_reference")
class RatingReference(RatingStudy):
    label = "Realism rating with a real reference"
    interface_words = ("real",)

    def default_instructions(self, study):
        return INSTRUCTIONS.format(n=study.clips_per_trial)

    def stimulus_roles(self, settings):
        return super().stimulus_roles(settings) | {Stimulus.Role.REFERENCE: 1}

    def add_shown(self, study, pool, plans, rng):
        """Give each trial a reference clip of its action."""
        references = pool.shown[Stimulus.Role.REFERENCE]
        for plan in plans:
            if references[plan.action]:
                reference = rng.choice(references[plan.action])
                plan.shown = [(reference, TrialItem.Role.REFERENCE, True)]

    def trial_context(self, study, trial, items):
        reference = next((i for i in items if i.role == TrialItem.Role.REFERENCE), None)
        return super().trial_context(study, trial, items) | {"reference": reference}
