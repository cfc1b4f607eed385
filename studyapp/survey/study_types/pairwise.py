"""Pairwise preference: two clips of one action side by side; which looks better?

As in recent motion-generation papers. Sources are balanced over the left and right
side; a study may also offer "both equally good" and "both equally bad" (option
``allow_ties``). The answer is stored on the trial; position 0 is the left clip, 1 the
right.
"""

from django import forms

from studyapp.participation.answers import Criterion
from studyapp.survey.study_types.base import Option, StudyType, registry

SIDES = ("Left clip", "Right clip")
CHOICES = {"left": "Left", "right": "Right", "both_good": "Both equally good",
           "both_bad": "Both equally bad"}
TIES = ("both_good", "both_bad")

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
    names = ["left", "right"] + (list(TIES) if study.option("allow_ties") else [])
    return [(name, CHOICES[name]) for name in names]


def chosen(choice: str, items):
    """Return the stimulus id of the preferred clip, or the tie itself."""
    sides = {item.position: item.stimulus_id for item in items}
    return {"left": sides[0], "right": sides[1]}.get(choice, choice)


@registry.register("pairwise")
class Pairwise(StudyType):
    label = "Pairwise preference"
    default_clips_per_trial = 2
    min_items = 2
    max_items = 2
    answer_seconds = 6.0
    default_criterion = Criterion("preference")
    options = {"allow_ties": Option(bool, False, 'Also offer "both equally good" and '
                                                 '"both equally bad".')}
    trial_answer = "choice"
    export_columns = ("choice",)

    def default_instructions(self, study):
        return INSTRUCTIONS.format(ties=TIES_TEXT if study.option("allow_ties") else "")

    def items_per_trial(self, study):
        return 2

    def item_label(self, item):
        return SIDES[item.position]

    def trial_context(self, study, trial, items):
        return {"choices": choices_of(study)}

    def trial_field(self, study, judged):
        return forms.ChoiceField(
            label="Your choice",
            choices=choices_of(study),
            error_messages={
                "required": "No clip is chosen yet.",
                "invalid_choice": "This answer is not one of the choices offered.",
            },
        )

    def catch_passed(self, answered):
        """The clip that is not broken must be preferred."""
        intact = next(item for item in answered.items if not item.stimulus.is_catch)
        return chosen(answered.choice, answered.items) == intact.stimulus_id

    def consistent(self, before, now):
        """The same clip is preferred again (or the same tie chosen)."""
        return chosen(before.choice, before.items) == chosen(now.choice, now.items)

    def instruct(self, study, n_judged, rng):
        return {"choice": rng.choice(["left", "right"])}

    def instruction_text(self, study, instruction, judged):
        return (f"choose \u201c{CHOICES[instruction['choice']]}\u201d, whatever you think of "
                f"the clips.")

    def obeyed(self, answered, instruction):
        return answered.choice == instruction["choice"]

    def obey(self, page, instruction, answer):
        return answer | {"choice": instruction["choice"]}

    def export_values(self, trial_answer, item_answer, item, items):
        return {"choice": trial_answer}

    def answer_fields(self, items, choice="left", **given):
        """``choice``: the trial's answer (default ``left``, clip A better)."""
        return {"choice": choice}

    def catch_answers(self, position):
        other = "right" if position == 0 else "left"
        return {"choice": other}, {"choice": "left" if position == 0 else "right"}

    def bot_answer(self, page, policy):
        left, right = (page.sources[token] for token in page.tokens)
        ties = [value for value in page.choices if value in TIES]
        return {"choice": policy.prefer(left, right, ties)}
