"""Forms of the participant pages other than trials (those are in ``answers``): consent
(with the study's screening questions) and the closing questions."""

from django import forms


class ConsentForm(forms.Form):
    """Agree (or decline) to take part, and answer the study's screening questions.

    ``outcome()`` is ``"no_consent"`` when the person declined, ``"screened_out"`` when a
    screening answer is not one the study accepts, else ``""``.
    """

    agree = forms.BooleanField(
        label="I have read the information above and agree to take part.", required=False,
    )

    def __init__(self, data=None, study=None):
        super().__init__(data)
        self.screening = study.platform.screening if study is not None else []
        for i, question in enumerate(self.screening):
            self.fields[f"screen_{i}"] = forms.ChoiceField(
                label=question["question"], widget=forms.RadioSelect,
                choices=[(a, a) for a in question["answers"]],
                error_messages={"required": "Please answer this question."},
            )

    def declined(self) -> bool:
        return bool(self.data.get("decline"))

    def clean(self):
        cleaned = super().clean()
        if self.declined():
            self.errors.clear()  # nothing else is needed to say no
            return {}
        if not cleaned.get("agree"):
            self.add_error("agree", "Please tick the box to agree before you continue.")
        return cleaned

    def outcome(self) -> str:
        if self.declined():
            return "no_consent"
        for i, question in enumerate(self.screening):
            if self.cleaned_data.get(f"screen_{i}") not in question["accept"]:
                return "screened_out"
        return ""


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
