"""Preference ranking (seed 000, Sec. 4.2.5): order N clips of one action, 1 = best.

A trial starts unranked: the answer exists only once the participant has ordered the
clips (or confirmed the order shown), so an untouched page cannot be submitted.
"""

from collections import Counter

from django import forms

from studyapp.participation.answers import Criterion
from studyapp.survey.study_types.base import StudyType, judged_at, registry

# A repeated ranking is consistent when clips move by at most this many places on average.
MAX_MEAN_RANK_CHANGE = 1.0

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows {n} short, silent clips \
of a figure performing it. The clips play on their own and repeat.

Watch every clip to the end at least once. Then put them in order, from the one you \
like most (rank 1) to the one you like least (rank {n}). Judge two things together: how \
natural and smooth the movement looks, and how well it shows the named action.

To order the clips, drag the rows of the ranking list, use the arrow buttons, or pick \
a rank from each row's menu; if the order shown is already yours, press "Keep this \
order". The submit button becomes active once every clip has played through and every \
clip has a rank.

There are no right or wrong answers; we are interested in your impression."""


@registry.register("ranking")
class Ranking(StudyType):
    label = "Preference ranking"
    default_clips_per_trial = 6
    one_per_source = True
    scripts = ("survey/ranking.js",)
    answer_seconds = 3.0
    default_criterion = Criterion("preference")
    item_prefix = "rank"
    export_columns = ("rank",)

    def default_instructions(self, study):
        return INSTRUCTIONS.format(n=study.clips_per_trial)

    def trial_context(self, study, trial, items):
        return {"ranks": range(1, len(items) + 1)}

    def item_field(self, study, item, label, n_items):
        return forms.IntegerField(
            label=f"Rank of {label.lower()}",
            min_value=1,
            max_value=n_items,
            error_messages={"required": f"{label} has no rank yet."},
        )

    def check_answer(self, study, values, judged):
        repeated = sorted(rank for rank, times in Counter(values.values()).items() if times > 1)
        if repeated:
            given = ", ".join(str(rank) for rank in repeated)
            return (f"Rank {given} is given to more than one clip; give each rank from 1 to "
                    f"{len(values)} to exactly one clip.")
        return None

    def catch_passed(self, answered):
        """The broken clip must be ranked last."""
        return answered.value(answered.catch()) == len(answered.items)

    def consistent(self, before, now):
        """Clips keep their ranks, give or take one place on average."""
        earlier = before.by_stimulus()
        moves = [abs(now.value(item) - before.value(earlier[item.stimulus_id]))
                 for item in now.items]
        return sum(moves) / len(moves) <= MAX_MEAN_RANK_CHANGE

    def instruct(self, study, n_judged, rng):
        return {"position": rng.randrange(n_judged), "rank": rng.randint(1, n_judged)}

    def instruction_text(self, study, instruction, judged):
        label = self.item_label(judged_at(judged, instruction["position"]))
        return f"give {label} rank {instruction['rank']}, whatever you think of it."

    def obeyed(self, answered, instruction):
        return answered.value(answered.at(instruction["position"])) == instruction["rank"]

    def obey(self, page, instruction, answer):
        """Swap ranks so that the clip asked about has the rank asked for."""
        wanted = f"rank_{page.tokens[instruction['position']]}"
        rank = str(instruction["rank"])
        holder = next(name for name, value in answer.items()
                      if name.startswith("rank_") and value == rank)
        return answer | {holder: answer[wanted], wanted: rank}

    def export_values(self, trial_answer, item_answer, item, items):
        return {"rank": item_answer}

    def answer_fields(self, items, ranks=None, **given):
        """``ranks``: positions to ranks (default: the screen order)."""
        return {f"rank_{item.token}": str((ranks or {}).get(item.position, item.position + 1))
                for item in items if item.role == "judged"}

    def catch_answers(self, position):
        others = [p for p in range(3) if p != position]
        return ({"ranks": {position: 3, **dict(zip(others, (1, 2)))}},
                {"ranks": {position: 1, **dict(zip(others, (2, 3)))}})

    def bot_answer(self, page, policy):
        order = policy.order([page.sources[token] for token in page.tokens])
        return {f"rank_{page.tokens[i]}": str(rank) for rank, i in enumerate(order, 1)}
