"""MUSHRA (ITU-R BS.1534): every clip of a trial scored 0-100 on a slider, at once.

Each trial shows one action's clips, one per source by default, and two more among them,
shuffled in like the others and never named: a hidden reference (a real clip, role
``reference``) and a low anchor (a clearly degraded real clip, role ``anchor``, made by
:func:`motion.perturb.low_anchor`). Both are judged items and exported as rows with
their ``stimulus_role``. A slider has no score until it is moved (its number box stays
empty), and the server requires a score of every clip: an untouched slider cannot be
sent.

The recommendation's post-screening (options ``screen_threshold``, ``screen_share``): a
participant who scores the hidden reference below 90 in more than 15 % of trials is left
out of the analysis (``analysis/mushra.py``).
"""

from django import forms

from studyapp.participation.answers import Criterion
from studyapp.survey.models import Stimulus
from studyapp.participation import assignment
from studyapp.survey.study_types.base import (
    Option,
    StudyType,
    TrialPlan,
    judged_at,
    registry,
    scores_consistent,
)

SCALE = (0, 100)
# The recommendation's five labelled intervals, top first.
BANDS = [(80, "Excellent"), (60, "Good"), (40, "Fair"), (20, "Poor"), (0, "Bad")]
# A catch clip is spotted when scored at most this (poor or bad); a repeat is consistent
# when no clip's score moves by more than MAX_CHANGE.
CATCH_MAX = 40
MAX_CHANGE = 20
HIDDEN = (Stimulus.Role.REFERENCE, Stimulus.Role.ANCHOR)

INSTRUCTIONS = """\
Each question names an action, for example "walk", and shows {n} short, silent clips of \
a figure performing it, side by side. The clips play on their own and repeat.

Watch every clip to the end at least once. Then score each clip with its slider, from 0 \
(bad) to 100 (excellent): how natural and convincing does the movement look, as the \
named action? Compare the clips with each other while you score: a question may hold \
clips of very different quality. Each slider starts without a score; move it (or type a \
number in its box) to give one. The submit button becomes active once every clip has \
played through and every clip has a score.

There are no right or wrong answers; we are interested in your impression."""


@registry.register("mushra")
class Mushra(StudyType):
    label = "MUSHRA (sliders 0-100, hidden reference and low anchor)"
    default_clips_per_trial = 4
    min_items = 1
    one_per_source = True
    answer_seconds = 6.0
    default_criterion = Criterion("quality")
    options = {
        "screen_threshold": Option(int, 90, "Post-screening: a hidden-reference score below "
                                            "this fails the trial."),
        "screen_share": Option(float, 0.15, "Post-screening: a participant failing more than "
                                            "this share of trials is left out of the analysis."),
    }
    item_prefix = "score"
    export_columns = ("score",)

    def default_instructions(self, study):
        return INSTRUCTIONS.format(n=study.clips_per_trial + len(HIDDEN))

    def check_options(self, options):
        if isinstance(options, dict) and isinstance(options.get("screen_share"), int) \
                and not isinstance(options["screen_share"], bool):
            options = {**options, "screen_share": float(options["screen_share"])}
        checked = super().check_options(options)
        low, high = SCALE
        threshold = checked.get("screen_threshold", 90)
        if not low <= threshold <= high:
            raise ValueError(f"screen_threshold: {threshold} must lie in {low}..{high}")
        share = checked.get("screen_share", 0.15)
        if not 0 <= share <= 1:
            raise ValueError(f"screen_share: {share} must lie in 0..1 (a share of trials)")
        return checked

    # --- stimuli and planning --------------------------------------------------------

    def stimulus_roles(self, settings):
        roles = super().stimulus_roles(settings) | {role: 1 for role in HIDDEN}
        if Stimulus.Role.PRACTICE in roles:  # as many as a trial shows, hidden ones included
            roles[Stimulus.Role.PRACTICE] += len(HIDDEN)
        return roles

    def plan_main(self, study, pool, rng):
        """Return main trials: one clip per source, least judged first, with the action's
        hidden reference and low anchor; all of them seated so that every source (the
        anchor too, the reference as its source) visits every place about equally."""
        n = self.items_per_trial(study)
        actions = rng.sample(sorted(pool.table), len(pool.table))
        plans = []
        for k in range((study.trials_per_participant or len(actions)) if actions else 0):
            action = actions[k % len(actions)]
            chosen = assignment.choose_balanced(pool.table[action], pool.items, rng, n)
            if len(chosen) < self.min_items:
                continue
            hidden = [rng.choice(stimuli) for role in HIDDEN
                      if (stimuli := pool.shown[role][action])]
            seats = assignment.order_positions(chosen + hidden, pool.positions, rng)
            for position, stimulus in enumerate(seats):
                pool.items[stimulus.pk] += 1
                pool.positions[(stimulus.source, position)] += 1
            plans.append(TrialPlan(action, seats))
        return plans

    def plan_practice(self, study, pool, rng):
        """The practice shows as many clips as a trial (the hidden two included), all of
        them practice clips (jittered real clips of a range of qualities)."""
        plan = super().plan_practice(study, pool, rng)
        if plan is not None:
            n = self.items_per_trial(study) + len(HIDDEN)
            spare = [s for s in pool.practice if s.action == plan.action and s not in plan.stimuli]
            plan.stimuli += rng.sample(spare, min(len(spare), n - len(plan.stimuli)))
        return plan

    def plan_catch(self, study, pool, stimulus, rng):
        plan = super().plan_catch(study, pool, stimulus, rng)
        if plan is not None:
            self._hide(plan, pool, rng)
        return plan

    def plan_instructed(self, study, pool, rng):
        """An instructed check shows the hidden reference and low anchor too, as every
        trial does."""
        plan = super().plan_instructed(study, pool, rng)
        if plan is not None:
            self._hide(plan, pool, rng)
        return plan

    @staticmethod
    def _hide(plan, pool, rng):
        """Put the action's hidden reference and low anchor among a catch trial's clips,
        each at a random place."""
        for role in HIDDEN:
            stimuli = pool.shown[role][plan.action]
            if stimuli:
                plan.stimuli.insert(rng.randint(0, len(plan.stimuli)), rng.choice(stimuli))

    # --- the trial page --------------------------------------------------------------

    def trial_context(self, study, trial, items):
        return {"bands": BANDS, "scale": SCALE}

    def item_field(self, study, item, label, n_items):
        low, high = SCALE
        return forms.IntegerField(
            label=f"Score of {label.lower()}",
            min_value=low,
            max_value=high,
            error_messages={"required": f"{label} has no score yet: move its slider."},
        )

    # --- grading ---------------------------------------------------------------------

    def catch_passed(self, answered):
        """The broken clip must score poor or bad (at most CATCH_MAX)."""
        return answered.value(answered.catch()) <= CATCH_MAX

    def consistent(self, before, now):
        """No clip's score moves by more than MAX_CHANGE."""
        return scores_consistent(before, now, MAX_CHANGE)

    # --- instructed-response checks ---------------------------------------------------

    def instruct(self, study, n_judged, rng):
        """Ask for one end of a slider: 0 or 100 is easy to give exactly."""
        return {"position": rng.randrange(n_judged), "score": rng.choice(SCALE)}

    def instruction_text(self, study, instruction, judged):
        label = self.item_label(judged_at(judged, instruction["position"]))
        end = "left" if instruction["score"] == SCALE[0] else "right"
        return (f"move the slider of {label} all the way to the {end}, to "
                f"{instruction['score']}, whatever you think of it.")

    def obeyed(self, answered, instruction):
        return answered.value(answered.at(instruction["position"])) == instruction["score"]

    def obey(self, page, instruction, answer):
        token = page.tokens[instruction["position"]]
        return answer | {f"score_{token}": str(instruction["score"])}

    def export_values(self, trial_answer, item_answer, item, items):
        return {"score": item_answer}

    def answer_fields(self, items, scores=None, **given):
        """``scores``: positions to 0-100 (default 50), the reference and anchor included."""
        return {f"score_{item.token}": str((scores or {}).get(item.position, 50))
                for item in items}

    def catch_answers(self, position):
        return {"scores": {position: 10}}, {"scores": {position: 80}}

    def bot_answer(self, page, policy):
        """A score of 50 at a utility of 1, plus 25 per unit of how good the clip looks to
        the policy (prefer-real: real clips 75-90, others 50-65, broken clips below 40)."""
        low, high = SCALE
        scores = {token: round(50 + 25 * (policy.utility(page.sources[token]) - 1))
                  for token in page.tokens}
        return {f"score_{token}": str(min(high, max(low, score)))
                for token, score in scores.items()}
