"""Preference ranking (seed 000, Sec. 4.2.5): order N clips of one action, 1 = best."""

from collections import Counter

from django import forms

from studyapp.survey.forms import TrialForm
from studyapp.survey.study_types.base import StudyType, by_stimulus, catch_item, registry

# A repeated ranking is consistent when clips move by at most this many places on average.
MAX_MEAN_RANK_CHANGE = 1.0

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows {n} short, silent clips \
of a figure performing it. The clips play on their own and repeat.

Watch every clip to the end at least once. Then put them in order, from the one you \
like most (rank 1) to the one you like least (rank {n}). Judge two things together: how \
natural and smooth the movement looks, and how well it shows the named action.

To order the clips, drag the rows of the ranking list, use the arrow buttons, or pick \
a rank from each row's menu. The submit button becomes active once every clip has \
played through.

There are no right or wrong answers; we are interested in your impression."""


class RankingForm(TrialForm):
    prefixes = ("rank", "plays")

    def add_item_fields(self, item, label):
        n = len(self.items)
        self.fields[f"rank_{item.stimulus.token}"] = forms.IntegerField(
            label=f"Rank of {label.lower()}",
            min_value=1,
            max_value=n,
            error_messages={"required": f"{label} has no rank."},
        )

    def clean(self):
        cleaned = super().clean()
        n = len(self.items)
        ranks = [cleaned.get(f"rank_{item.stimulus.token}") for item in self.items]
        if None in ranks:
            return cleaned
        repeated = sorted(rank for rank, times in Counter(ranks).items() if times > 1)
        if repeated:
            given = ", ".join(str(rank) for rank in repeated)
            raise forms.ValidationError(
                f"Rank {given} is given to more than one clip; "
                f"give each rank from 1 to {n} to exactly one clip."
            )
        return cleaned


@registry.register("ranking")
class Ranking(StudyType):
    label = "Preference ranking"
    default_clips_per_trial = 6
    trial_template = "survey/trial_ranking.html"
    scripts = ("survey/ranking.js",)
    form_class = RankingForm
    minutes = 10

    def default_instructions(self, study):
        return INSTRUCTIONS.format(n=study.clips_per_trial)

    def catch_passed(self, trial, items):
        """The broken clip must be ranked last."""
        return catch_item(items).rank == len(items)

    def consistent(self, before, before_items, trial, items):
        """Clips keep their ranks, give or take one place on average."""
        earlier = by_stimulus(before_items)
        moves = [abs(item.rank - earlier[item.stimulus_id].rank) for item in items]
        return sum(moves) / len(moves) <= MAX_MEAN_RANK_CHANGE

    def simulate_answer(self, page, policy):
        order = policy.order([page.sources[token] for token in page.tokens])
        return {f"rank_{page.tokens[i]}": str(rank) for rank, i in enumerate(order, 1)}
