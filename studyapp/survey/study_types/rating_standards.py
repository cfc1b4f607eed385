"""Realism rating with scoring standards (seed 003, Table 3, appendix Fig. 9).

Each trial page first shows the five scoring standards of its action, each a
description and an example clip (:class:`~studyapp.survey.models.ScoringStandard`),
so that every rater uses the same scale; then the blind clips, each scored 1-5. The
examples must be watched the first time an action's standards are shown; later trials
of the action show them folded behind "show examples", never playing with the clips.
"""

from studyapp.survey.models import ScoringStandard, Stimulus, TrialItem
from studyapp.survey.study_types.base import registry
from studyapp.survey.study_types.rating import RatingStudy

SCORES = (1, 2, 3, 4, 5)
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

The first question of each action starts with its scoring standard: five example clips, \
one for each score from 1 (not realistic at all) to 5 (completely realistic), each with \
a description. Use them so that your scores mean the same as everyone else's; later \
questions keep them one tap away ("Show examples").

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

    def stimulus_roles(self, settings):
        return super().stimulus_roles(settings) | {Stimulus.Role.EXAMPLE: len(SCORES)}

    def after_register(self, study, clips, stimuli):
        """Make each action's standards from its example clips (``clip.score``)."""
        examples: dict[str, dict] = {}
        for clip, stimulus in zip(clips, stimuli):
            if clip.role == Stimulus.Role.EXAMPLE:
                examples.setdefault(clip.action, {})[clip.score] = stimulus
        for action, chosen in examples.items():
            have = {s.score: s.stimulus_id for s in ScoringStandard.objects.for_action(study, action)}
            if have != {score: s.pk for score, s in chosen.items()}:
                ScoringStandard.objects.set_standards(
                    study, action, chosen, default_descriptions(action.replace("_", " ")))

    def add_shown(self, study, pool, plans, rng):
        """Show each trial its action's examples; required the first time only."""
        standards = {}
        for standard in ScoringStandard.objects.filter(study=study).select_related("stimulus"):
            standards.setdefault(standard.action, []).append(standard)
        seen = set()
        for plan in plans:
            mine = sorted(standards.get(plan.action, []), key=lambda s: s.score)
            first = plan.action not in seen
            seen.add(plan.action)
            plan.shown = [(s.stimulus, TrialItem.Role.EXAMPLE, first) for s in mine]

    def trial_context(self, study, trial, items):
        examples = [i for i in items if i.role == TrialItem.Role.EXAMPLE]
        standards = {s.stimulus_id: s for s in ScoringStandard.objects.for_action(study, trial.action)}
        for item in examples:
            standard = standards.get(item.stimulus_id)
            item.score = standard.score if standard else None
            item.description = standard.description if standard else ""
        folded = bool(examples) and not any(item.required for item in examples)
        return super().trial_context(study, trial, items) | {
            "standards": examples, "standards_folded": folded,
        }
