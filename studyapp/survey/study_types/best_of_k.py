"""Best of K (the MotionPercept protocol): K clips of one action; which one is best?

Each trial shows ``k`` clips of one action (option ``k``; by default the study's
``clips_per_trial``, 4), sources balanced over the clips and their positions. The
participant picks the best clip, or says that the clips are all good or all bad, when
none stands out. The answer is stored on the
trial: the position of the chosen clip, or ``"all_good"`` / ``"all_bad"``.
"""

from django import forms

from studyapp.participation.answers import Criterion
from studyapp.survey.study_types.base import Option, StudyType, judged_at, registry

ALL_GOOD, ALL_BAD = "all_good", "all_bad"
NONE_BEST = {ALL_GOOD: "All good", ALL_BAD: "All bad"}
DEFAULT_K = 4

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows {k} short, silent clips of \
a figure performing it. The clips play on their own and repeat.

Watch every clip to the end at least once. Then choose the best one: the movement that \
looks most natural and shows the named action best. If no clip stands out because they \
all look good, choose "All good"; if they all look bad, choose "All bad". Please use \
these two only when you really cannot pick one clip. The submit button becomes active \
once every clip has played through and you have chosen.

There are no right or wrong answers; we are interested in your impression."""


def picked(value, items):
    """Return the stimulus id of the clip picked by ``value`` (a position), or the
    "all good"/"all bad" answer itself."""
    if value in NONE_BEST:
        return value
    return next((item.stimulus_id for item in items if item.position == value), None)


@registry.register("best_of_k")
class BestOfK(StudyType):
    label = "Best of K"
    default_clips_per_trial = DEFAULT_K
    min_items = 2
    answer_seconds = 6.0
    default_criterion = Criterion("preference")
    options = {"k": Option(int, None, "Clips per trial, of which the best is chosen (default: "
                                      "clips_per_trial, 4).")}
    trial_answer = "pick"
    export_columns = ("pick",)

    def default_instructions(self, study):
        return INSTRUCTIONS.format(k=self.items_per_trial(study))

    def items_per_trial(self, study):
        return self.option(study, "k") or study.clips_per_trial

    def check_options(self, options):
        checked = super().check_options(options)
        if checked.get("k", self.min_items) < self.min_items:
            raise ValueError(f"k: {checked['k']} must be at least {self.min_items} "
                             f"(clips per trial)")
        return checked

    def trial_context(self, study, trial, items):
        return {"none_best": list(NONE_BEST.items())}

    def trial_field(self, study, judged):
        choices = [(item.token, self.item_label(item)) for item in judged]
        return forms.ChoiceField(
            label="Your choice",
            choices=choices + list(NONE_BEST.items()),
            error_messages={
                "required": 'No clip is chosen yet (or "All good" / "All bad").',
                "invalid_choice": "This answer is not one of the clips or choices offered.",
            },
        )

    def trial_value(self, value, judged):
        """Store the picked clip's position, or the "all good"/"all bad" answer."""
        if value in NONE_BEST:
            return value
        return next(item.position for item in judged if item.token == value)

    def catch_passed(self, answered):
        """Another clip is best, or all are bad: never the broken clip, never "all good"."""
        choice = picked(answered.choice, answered.items)
        return choice == ALL_BAD or choice not in (ALL_GOOD, answered.catch().stimulus_id, None)

    def consistent(self, before, now):
        """The same clip is picked again (or the same "all good"/"all bad")."""
        return picked(before.choice, before.items) == picked(now.choice, now.items)

    def instruct(self, study, n_judged, rng):
        return {"position": rng.randrange(n_judged)}

    def instruction_text(self, study, instruction, judged):
        label = self.item_label(judged_at(judged, instruction["position"]))
        return f"choose {label} as the best, whatever you think of it."

    def obeyed(self, answered, instruction):
        return answered.choice == instruction["position"]

    def obey(self, page, instruction, answer):
        return answer | {"pick": page.tokens[instruction["position"]]}

    def export_values(self, trial_answer, item_answer, item, items):
        """``pick`` per clip: ``best`` (the picked clip), ``other``, ``all_good``, ``all_bad``."""
        if trial_answer is None:
            return {"pick": None}
        if trial_answer in NONE_BEST:
            return {"pick": trial_answer}
        return {"pick": "best" if trial_answer == item["position"] else "other"}

    def answer_fields(self, items, pick=None, **given):
        """``pick``: the position picked (default 0), or ``all_good`` / ``all_bad``."""
        judged = {item.position: item.token for item in items if item.role == "judged"}
        return {"pick": pick if isinstance(pick, str) else judged[pick or 0]}

    def catch_answers(self, position):
        return {"pick": 1 if position == 0 else 0}, {"pick": position}

    def bot_answer(self, page, policy):
        """The clip that looks best to the policy (a Plackett-Luce first choice for ``bt``)."""
        looks = {token: policy.utility(page.sources[token]) for token in page.tokens}
        return {"pick": max(page.tokens, key=looks.get)}
