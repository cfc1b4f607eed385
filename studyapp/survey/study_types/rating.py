"""What the two realism-rating protocols share: a 1-5 score for each clip of a trial.

Not a study type itself; :mod:`.rating_standards` and :mod:`.rating_reference` add what
is shown beside the clips (scoring standards, or a real reference clip).
"""

from django import forms

from studyapp.survey.forms import TrialForm
from studyapp.survey.study_types.base import StudyType, by_stimulus, catch_item

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


class RatingForm(TrialForm):
    prefixes = ("rating", "plays")

    def add_item_fields(self, item, label):
        self.fields[f"rating_{item.stimulus.token}"] = forms.IntegerField(
            label=f"Score of {label.lower()}",
            min_value=1,
            max_value=len(SCALE),
            error_messages={"required": f"{label} has no score yet."},
        )


class RatingStudy(StudyType):
    """Score every clip of a trial from 1 (not realistic) to 5 (completely realistic)."""

    default_clips_per_trial = 4
    min_items = 1
    trial_template = "survey/trial_rating.html"
    scripts = ("survey/choices.js",)
    form_class = RatingForm
    minutes = 10

    def trial_context(self, trial, items):
        return {"scale": SCALE}

    def catch_passed(self, trial, items):
        """The broken clip must get a low score."""
        return catch_item(items).rating <= CATCH_MAX

    def consistent(self, before, before_items, trial, items):
        """No clip's score changes by more than one."""
        earlier = by_stimulus(before_items)
        return all(
            abs(item.rating - earlier[item.stimulus_id].rating) <= MAX_CHANGE for item in items
        )

    def simulate_answer(self, page, policy):
        return {f"rating_{token}": str(policy.rating(page.sources[token])) for token in page.tokens}
