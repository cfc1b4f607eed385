"""The base every study type subclasses, and the registry they join.

A type says what one trial shows and asks (``items_per_trial``, its template and form),
how a catch trial is graded and when a repeated trial counts as consistent, and how a
simulated participant answers. Planning a session (balanced main trials, practice,
catch and repeated trials) is shared here and in :mod:`studyapp.survey.assignment`.
"""

from collections import Counter
from dataclasses import dataclass, field

from generation.registry import Registry
from studyapp.survey import assignment
from studyapp.survey.forms import clip_label
from studyapp.survey.models import Trial

registry = Registry("study type")

DEFAULT_CONSENT = """\
This study is part of academic research on how people perceive human movement. \
You will watch short, silent animations of a figure moving and answer questions about them. \
It takes about {minutes} minutes.

Taking part is voluntary and you may stop at any time by closing the page. \
We store your answers, the time you took and the platform id you arrived with; \
we do not ask for your name or any other personal information. \
The anonymous answers may be published for research."""


@dataclass(eq=False)
class TrialPlan:
    """One trial to create: its action, its stimuli in display order, and its kind.

    Plans compare by identity, so a repeat can point at the plan it repeats.
    """

    action: str
    stimuli: list = field(default_factory=list)
    kind: str = Trial.Kind.MAIN
    repeat_of: "TrialPlan | None" = None
    reference: object = None


class StudyType:
    """What differs between study protocols; the flow around it is shared."""

    name = ""
    label = ""
    default_clips_per_trial = 6
    min_items = 2
    max_items: int | None = None
    trial_template = ""
    scripts: tuple[str, ...] = ()
    form_class = None
    minutes = 5
    # Words of this type's questions that are also source names ("real" in "real or
    # generated"): allowed on its pages only because every trial page shows them alike.
    interface_words: tuple[str, ...] = ()

    def default_instructions(self, study) -> str:
        raise NotImplementedError

    def item_label(self, position: int) -> str:
        """Return the name a participant sees for the clip at ``position``."""
        return clip_label(position)

    @property
    def default_consent(self) -> str:
        return DEFAULT_CONSENT.format(minutes=self.minutes)

    # Planning

    def items_per_trial(self, study) -> int:
        return study.clips_per_trial

    def trials_per_action(self, study, table) -> int:
        """Return how many main trials each action gets by default."""
        return 1

    def plan_trials(self, study, rng) -> list[TrialPlan]:
        """Return the trials of a new participant; called with the study row locked.

        Main trials first draw on ``rng`` exactly as a session without extras would,
        so the practice, catch and repeated trials never change which clips a
        participant judges.
        """
        pool = assignment.Pool.of(study)
        main = self.plan_main(study, pool, rng)
        practice = self.plan_practice(study, pool, rng) if study.practice else None
        catch = [
            plan
            for stimulus in assignment.pick_catch(pool.catches, study.catch_trials, rng)
            if (plan := self.plan_catch(study, pool, stimulus, rng)) is not None
        ]
        session = assignment.arrange(main, catch, study.repeat_trials, rng)
        return ([practice] if practice else []) + session

    def plan_main(self, study, pool, rng) -> list[TrialPlan]:
        """Return balanced main trials: the least-judged stimuli, sources over positions."""
        n = self.items_per_trial(study)
        actions = rng.sample(sorted(pool.table), len(pool.table))
        per_action = self.trials_per_action(study, pool.table)
        if per_action > 1:
            actions = [action for action in actions for _ in range(per_action)]
            rng.shuffle(actions)
        wanted = study.trials_per_participant or len(actions)
        plans = []
        for k in range(wanted if actions else 0):
            action = actions[k % len(actions)]
            seats = assignment.assign(pool.table[action], pool.items, pool.positions, rng, n)
            if len(seats) >= self.min_items:
                plans.append(TrialPlan(action, seats))
        return plans

    def plan_practice(self, study, pool, rng) -> TrialPlan | None:
        """Return a practice trial of random clips (not counted in the balance)."""
        if not pool.table:
            return None
        action = rng.choice(sorted(pool.table))
        stimuli = assignment.choose_balanced(
            pool.table[action], Counter(), rng, self.items_per_trial(study)
        )
        rng.shuffle(stimuli)
        if len(stimuli) < self.min_items:
            return None
        return TrialPlan(action, stimuli, Trial.Kind.PRACTICE)

    def plan_catch(self, study, pool, stimulus, rng) -> TrialPlan | None:
        """Return a trial showing the broken clip ``stimulus`` among clips of its action."""
        fill = assignment.choose_balanced(
            pool.table.get(stimulus.action, {}), Counter(), rng, self.items_per_trial(study) - 1
        )
        stimuli = fill + [stimulus]
        rng.shuffle(stimuli)
        if len(stimuli) < self.min_items:
            return None
        return TrialPlan(stimulus.action, stimuli, Trial.Kind.CATCH)

    # Answers

    def answer_form(self, trial, items, data):
        """Return the bound form that checks a POST answering ``trial``."""
        return self.form_class(trial, items, data)

    def trial_context(self, trial, items) -> dict:
        """Return extra template context for the trial page."""
        return {}

    def grade(self, trial, items) -> bool | None:
        """Return whether a catch trial was passed or a repeat answered as before."""
        if trial.kind == Trial.Kind.CATCH:
            return self.catch_passed(trial, items)
        if trial.kind == Trial.Kind.REPEAT and trial.repeat_of_id:
            before = trial.repeat_of
            earlier = list(before.items.select_related("stimulus"))
            return self.consistent(before, earlier, trial, items)
        return None

    def catch_passed(self, trial, items) -> bool:
        """Return whether the answer treats the broken clip as the worst."""
        raise NotImplementedError

    def consistent(self, before, before_items, trial, items) -> bool:
        """Return whether a repeated trial got the same answer as the trial it repeats."""
        raise NotImplementedError

    def simulate_answer(self, page, policy) -> dict:
        """Return the answer fields a simulated participant posts for a trial page.

        ``page.tokens`` are the clips in screen order, ``page.sources`` their sources
        (looked up in the database, never read from the page).
        """
        raise NotImplementedError


def catch_item(items):
    """Return the broken clip of a catch trial."""
    return next(item for item in items if item.stimulus.is_catch)


def by_stimulus(items) -> dict:
    return {item.stimulus_id: item for item in items}
