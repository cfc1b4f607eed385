"""Graded pairwise preference: two clips side by side, answered on a symmetric 7-point scale.

The scale runs from "A much better" through "No preference" to "B much better"; clip A
is the left clip (position 0), clip B the right one (position 1). A study may also offer
"Both bad" (option ``both_bad``, on by default) for pairs where neither clip is
acceptable. Sources are balanced over the two sides, as in :mod:`.pairwise`.

The answer is stored on the trial as a side-based value (``left_much`` ... ``right_much``,
``no_preference``, ``both_bad``: "left" is clip A); the export gives it as ``choice`` on
both clips' rows and, per row, ``grade``: how much better this clip was judged than the
other, from +3 (much better) to -3 (much worse), blank for "Both bad".
"""

from django import forms

from studyapp.participation.answers import Criterion
from studyapp.survey.study_types.base import Option, StudyType, registry

# (stored value, what the participant reads, grade of clip A)
SCALE = (
    ("left_much", "A much better", 3),
    ("left", "A better", 2),
    ("left_slightly", "A slightly better", 1),
    ("no_preference", "No preference", 0),
    ("right_slightly", "B slightly better", -1),
    ("right", "B better", -2),
    ("right_much", "B much better", -3),
)
BOTH_BAD = ("both_bad", "Both bad")
GRADE_OF_A = {value: grade for value, _, grade in SCALE}
VALUES = tuple(GRADE_OF_A) + (BOTH_BAD[0],)
# A repeated trial is consistent when the same clip's grade moves by at most this and
# never crosses to the other clip.
MAX_CHANGE = 1
# How far apart two clips look to a bot (policy utilities) for each grade.
BOT_STEPS = (0.25, 1.0, 2.0)
BOT_BOTH_BAD = -1.5

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows two short, silent clips of \
a figure performing it, side by side: clip A on the left, clip B on the right. The clips \
play on their own and repeat.

Watch both clips to the end at least once. Then say which one you prefer, and by how \
much, on a scale from "A much better" through "No preference" to "B much better": the \
movement that looks more natural and shows the named action better.{both_bad} The \
submit button becomes active once both clips have played through. You can also press \
the keys 1 to 7 to choose a point of the scale, from left to right.

There are no right or wrong answers; we are interested in your impression."""

BOTH_BAD_TEXT = """ If neither clip looks acceptable, choose "Both bad"; please use it \
only when both clips really look wrong."""


def choices_of(study) -> list[tuple[str, str]]:
    """Return the answers a graded trial of ``study`` offers, the scale first."""
    out = [(value, text) for value, text, _ in SCALE]
    return out + [BOTH_BAD] if study.option("both_bad") else out


def grade_of(choice, position: int):
    """Return how much better the clip at ``position`` was judged than the other one
    (+3 .. -3), or None for "Both bad" or no answer."""
    grade = GRADE_OF_A.get(choice)
    if grade is None:
        return None
    return grade if position == 0 else -grade


def stimulus_grade(answered, stimulus_id):
    """Return the grade a trial's answer gives the clip of ``stimulus_id``."""
    item = next(item for item in answered.items if item.stimulus_id == stimulus_id)
    return grade_of(answered.choice, item.position)


@registry.register("pairwise_graded")
class PairwiseGraded(StudyType):
    label = "Graded pairwise preference"
    default_clips_per_trial = 2
    min_items = 2
    max_items = 2
    answer_seconds = 7.0
    default_criterion = Criterion("preference")
    options = {"both_bad": Option(bool, True, 'Also offer "Both bad" beside the 7-point scale.')}
    trial_answer = "choice"
    export_columns = ("choice", "grade")

    def default_instructions(self, study):
        return INSTRUCTIONS.format(both_bad=BOTH_BAD_TEXT if study.option("both_bad") else "")

    def items_per_trial(self, study):
        return 2

    def trial_context(self, study, trial, items):
        return {"scale": [(value, text, i + 1) for i, (value, text, _) in enumerate(SCALE)],
                "both_bad": BOTH_BAD if study.option("both_bad") else None}

    def trial_field(self, study, judged):
        return forms.ChoiceField(
            label="Your answer",
            choices=choices_of(study),
            error_messages={
                "required": "No point of the scale is chosen yet.",
                "invalid_choice": "This answer is not one of the choices offered.",
            },
        )

    def catch_passed(self, answered):
        """The clip that is not broken must be judged better (by any step of the scale)."""
        intact = next(item for item in answered.items if not item.stimulus.is_catch)
        return (grade_of(answered.choice, intact.position) or 0) > 0

    def consistent(self, before, now):
        """The same answer again, give or take one step, and never for the other clip:
        the grade of the same clip moves by at most one step and does not change sign
        ("Both bad" is consistent only with "Both bad")."""
        first = before.items[0].stimulus_id
        was, is_now = stimulus_grade(before, first), stimulus_grade(now, first)
        if was is None or is_now is None:
            return was is None and is_now is None
        return abs(was - is_now) <= MAX_CHANGE and was * is_now >= 0

    def instruct(self, study, n_judged, rng):
        return {"choice": rng.choice(SCALE)[0]}

    def instruction_text(self, study, instruction, judged):
        said = next(text for value, text, _ in SCALE if value == instruction["choice"])
        return f"choose \u201c{said}\u201d on the scale, whatever you think of the clips."

    def obeyed(self, answered, instruction):
        return answered.choice == instruction["choice"]

    def obey(self, page, instruction, answer):
        return answer | {"choice": instruction["choice"]}

    def export_values(self, trial_answer, item_answer, item, items):
        return {"choice": trial_answer, "grade": grade_of(trial_answer, item["position"])}

    def answer_fields(self, items, choice="left", **given):
        """``choice``: the trial's answer (default ``left``, clip A better)."""
        return {"choice": choice}

    def catch_answers(self, position):
        return ({"choice": "right_slightly" if position == 0 else "left_much"},
                {"choice": "no_preference"})

    def bot_answer(self, page, policy):
        a, b = (page.sources[token] for token in page.tokens)
        u_a, u_b = policy.utility(a), policy.utility(b)
        if "both_bad" in page.choices and max(u_a, u_b) < BOT_BOTH_BAD:
            return {"choice": "both_bad"}
        gap = u_a - u_b
        steps = sum(abs(gap) >= step for step in BOT_STEPS)
        grade = steps if gap > 0 else -steps
        return {"choice": next(value for value, _, g in SCALE if g == grade)}
