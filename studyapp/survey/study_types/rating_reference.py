"""Realism rating with a real reference clip (seed 004, Table 5).

Participants are told the action and shown one real clip of it (a stimulus marked
``is_reference``, never rated), then score each clip 1-5.
"""

from collections import defaultdict

from studyapp.survey.models import Stimulus
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
active once they have all played through. Choose a score with the buttons under each clip.

There are no right or wrong answers; we are interested in your impression."""


@registry.register("rating_reference")
class RatingReference(RatingStudy):
    label = "Realism rating with a real reference"
    interface_words = ("real",)

    def default_instructions(self, study):
        return INSTRUCTIONS.format(n=study.clips_per_trial)

    def plan_trials(self, study, rng):
        """Plan as usual, then give each trial a reference clip of its action."""
        plans = super().plan_trials(study, rng)
        references = defaultdict(list)
        for stimulus in Stimulus.objects.filter(study=study, is_reference=True).order_by("pk"):
            references[stimulus.action].append(stimulus)
        for plan in plans:
            if plan.repeat_of is not None:
                plan.reference = plan.repeat_of.reference
            elif references[plan.action]:
                plan.reference = rng.choice(references[plan.action])
        return plans

    def trial_context(self, trial, items):
        return super().trial_context(trial, items) | {"reference": trial.reference}
