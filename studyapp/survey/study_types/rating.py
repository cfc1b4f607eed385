"""What the two realism-rating protocols share: a 1-5 score for each clip of a trial.

Not a study type itself; :mod:`.rating_standards` and :mod:`.rating_reference` add what
is shown beside the clips (scoring standards, or a real reference clip). Both use the
template ``rating.html`` beside this module.
"""

from django import forms

from studyapp.participation.answers import Criterion
from studyapp.survey.study_types.base import StudyType, judged_at, scores_consistent

SCALE = [
    (1, "Not realistic at all"),
    (2, "Hardly realistic"),
    (3, "Somewhat realistic"),
    (4, "Quite realistic"),
    (5, "Completely realistic"),
]
# A catch clip is spotted when scored at most this; a repeat is consistent when no clip
# moves by more than MAX_CHANGE.
CATCH_MAX = 2
MAX_CHANGE = 1


class RatingStudy(StudyType):
    """Score every clip of a trial from 1 (not realistic) to 5 (completely realistic)."""

    default_clips_per_trial = 4
    min_items = 1
    one_per_source = True
    template = "rating.html"
    answer_seconds = 4.0
    default_criterion = Criterion("realism")
    item_prefix = "rating"
    export_columns = ("rating",)

    def trial_context(self, study, trial, items):
        return {"scale": SCALE}

    def item_field(self, study, item, label, n_items):
        return forms.IntegerField(
            label=f"Score of {label.lower()}",
            min_value=1,
            max_value=len(SCALE),
            error_messages={"required": f"{label} has no score yet."},
        )

    def catch_passed(self, answered):
        """The broken clip must get a low score."""
        return answered.value(answered.catch()) <= CATCH_MAX

    def consistent(self, before, now):
        """No clip's score changes by more than one."""
        return scores_consistent(before, now, MAX_CHANGE)

    def instruct(self, study, n_judged, rng):
        return {"position": rng.randrange(n_judged), "score": rng.choice(SCALE)[0]}

    def instruction_text(self, study, instruction, judged):
        label = self.item_label(judged_at(judged, instruction["position"]))
        return f"give {label} a score of {instruction['score']}, whatever you think of it."

    def obeyed(self, answered, instruction):
        return answered.value(answered.at(instruction["position"])) == instruction["score"]

    def obey(self, page, instruction, answer):
        token = page.tokens[instruction["position"]]
        return answer | {f"rating_{token}": str(instruction["score"])}

    def export_values(self, trial_answer, item_answer, item, items):
        return {"rating": item_answer}

    def answer_fields(self, items, ratings=None, **given):
        """``ratings``: positions to ratings (default 3)."""
        return {f"rating_{item.token}": str((ratings or {}).get(item.position, 3))
                for item in items if item.role == "judged"}

    def catch_answers(self, position):
        return {"ratings": {position: CATCH_MAX}}, {"ratings": {position: CATCH_MAX + 2}}

    def bot_answer(self, page, policy):
        return {f"rating_{token}": str(policy.rating(page.sources[token])) for token in page.tokens}
