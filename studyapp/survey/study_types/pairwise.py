"""Pairwise preference: two clips of one action side by side; which looks better?

As in recent motion-generation papers. Sources are balanced over the left and right
side; a study may also offer "both equally good" and "both equally bad"
(``Study.allow_ties``). The answer is the trial's ``choice``; position 0 is the left
clip, 1 the right.
"""

from django import forms

from studyapp.survey.forms import TrialForm
from studyapp.survey.models import Trial
from studyapp.survey.study_types.base import StudyType, registry

SIDES = ("Left clip", "Right clip")
TIES = (Trial.Choice.BOTH_GOOD, Trial.Choice.BOTH_BAD)

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows two short, silent clips of \
a figure performing it, side by side. The clips play on their own and repeat.

Watch both clips to the end at least once. Then choose the one you prefer: the movement \
that looks more natural and shows the named action better.{ties} The submit button \
becomes active once both clips have played through. You can also press the left or \
right arrow key to choose.

There are no right or wrong answers; we are interested in your impression."""

TIES_TEXT = """ If you cannot tell them apart, choose "both equally good" or "both equally \
bad"; please use these only when you really have no preference."""


def choices_of(study) -> list[tuple[str, str]]:
    """Return the answers a pairwise trial of ``study`` offers."""
    sides = [(Trial.Choice.LEFT, "Left"), (Trial.Choice.RIGHT, "Right")]
    ties = [(value, Trial.Choice(value).label) for value in TIES] if study.allow_ties else []
    return [(str(value), label) for value, label in sides + ties]


class PairwiseForm(TrialForm):
    prefixes = ("plays",)

    def __init__(self, trial, items, data):
        super().__init__(trial, items, data)
        self.fields["choice"] = forms.ChoiceField(
            label="Your choice",
            choices=choices_of(trial.participant.study),
            error_messages={
                "required": "No clip is chosen yet.",
                "invalid_choice": "This answer is not one of the choices offered.",
            },
        )

    def label(self, item):
        return SIDES[item.position]

    def trial_answer(self):
        return {"choice": self.cleaned_data["choice"]}


def chosen(choice: str, items):
    """Return the stimulus id of the preferred clip, or the tie itself."""
    sides = {item.position: item.stimulus_id for item in items}
    return {Trial.Choice.LEFT: sides[0], Trial.Choice.RIGHT: sides[1]}.get(choice, choice)


@registry.register("pairwise")
class Pairwise(StudyType):
    label = "Pairwise preference"
    default_clips_per_trial = 2
    min_items = 2
    max_items = 2
    trial_template = "survey/trial_pairwise.html"
    scripts = ("survey/choices.js",)
    form_class = PairwiseForm
    minutes = 8

    def default_instructions(self, study):
        return INSTRUCTIONS.format(ties=TIES_TEXT if study.allow_ties else "")

    def items_per_trial(self, study):
        return 2

    def item_label(self, position):
        return SIDES[position]

    def trial_context(self, trial, items):
        return {"choices": choices_of(trial.participant.study)}

    def catch_passed(self, trial, items):
        """The clip that is not broken must be preferred."""
        intact = next(item for item in items if not item.stimulus.is_catch)
        return chosen(trial.choice, items) == intact.stimulus_id

    def consistent(self, before, before_items, trial, items):
        """The same clip is preferred again (or the same tie chosen)."""
        return chosen(before.choice, before_items) == chosen(trial.choice, items)

    def simulate_answer(self, page, policy):
        left, right = (page.sources[token] for token in page.tokens)
        ties = [value for value in page.choices if value in TIES]
        return {"choice": policy.prefer(left, right, ties)}
