"""Forms of the participant pages: consent, demographics, and the base of every answer."""

import re
import string

from django import forms
from django.core.exceptions import NON_FIELD_ERRORS

MAX_PLAYS = 100_000


def clip_label(position: int) -> str:
    """Return the name a participant sees for the clip at ``position`` ("Clip A")."""
    letters = string.ascii_uppercase
    name = letters[position % 26] * (position // 26 + 1)
    return f"Clip {name}"


class ConsentForm(forms.Form):
    agree = forms.BooleanField(
        label="I have read the information above and agree to take part.",
        error_messages={"required": "Please tick the box to agree before you continue."},
    )


AGE_RANGES = ["18-24", "25-34", "35-44", "45-54", "55-64", "65+"]
GENDERS = [("woman", "Woman"), ("man", "Man"), ("non_binary", "Non-binary"), ("other", "Other")]
NO_ANSWER = ("", "Prefer not to say")


class DemographicsForm(forms.Form):
    """A few optional questions at the end; every one may be left blank."""

    age_range = forms.ChoiceField(
        label="Age", required=False, choices=[NO_ANSWER] + [(a, a) for a in AGE_RANGES]
    )
    gender = forms.ChoiceField(label="Gender", required=False, choices=[NO_ANSWER] + GENDERS)
    comments = forms.CharField(
        label="Comments (optional)",
        required=False,
        max_length=2000,
        widget=forms.Textarea(attrs={"rows": 4}),
        help_text="Anything about the study you would like us to know, e.g. a problem with a clip.",
    )


class TrialForm(forms.Form):
    """Check an answer to one trial: every item of it exactly once, each played.

    Fields are named ``<prefix>_<stimulus token>``; a field naming a clip that is not in
    this trial makes the whole answer invalid rather than being ignored. Subclasses add
    each item's answer field (``add_item_fields``) and may answer on the trial itself
    (``trial_answer``, e.g. a pairwise choice).
    """

    prefixes = ("plays",)

    def __init__(self, trial, items, data):
        super().__init__(data)
        self.trial = trial
        self.items = list(items)
        for item in self.items:
            label = self.label(item)
            self.fields[f"plays_{item.stimulus.token}"] = forms.IntegerField(
                label=f"Plays of {label.lower()}",
                min_value=1,
                max_value=MAX_PLAYS,
                error_messages={
                    "required": f"{label} is missing from the answer.",
                    "min_value": f"{label} has not been played to the end yet.",
                },
            )
            self.add_item_fields(item, label)

    def label(self, item) -> str:
        """Return the name the participant sees for an item."""
        return clip_label(item.position)

    def add_item_fields(self, item, label: str) -> None:
        """Add the answer fields of one item (subclasses)."""

    def clean(self):
        tokens = {item.stimulus.token for item in self.items}
        pattern = re.compile(rf"^({'|'.join(self.prefixes)})_(.+)$")
        for key in self.data:
            match = pattern.match(key)
            if match and match.group(2) not in tokens:
                raise forms.ValidationError("The answer names a clip that is not in this question.")
        return super().clean()

    def item_answer(self, item) -> dict:
        """Return the model fields of one item's answer (by default, one per prefix)."""
        token = item.stimulus.token
        return {prefix: self.cleaned_data[f"{prefix}_{token}"] for prefix in self.prefixes}

    def answers(self) -> dict[int, dict]:
        """Return ``{item id: {field: value}}`` ready for ``Trial.objects.record_answer``."""
        return {item.pk: self.item_answer(item) for item in self.items}

    def trial_answer(self) -> dict:
        """Return the answer fields stored on the trial itself."""
        return {}

    def messages(self) -> list[str]:
        """Return every error as one plain sentence."""
        out = list(self.non_field_errors())
        for name, errors in self.errors.items():
            if name == NON_FIELD_ERRORS:
                continue
            label = self.fields[name].label
            names = tuple(self.label(item) for item in self.items)
            out += [e if e.startswith(names) else f"{label}: {e}" for e in errors]
        return out
