"""The base every study type subclasses, and the registry they join.

A study type owns everything that depends on it, and nothing else in the app branches on
its key:

- its study options (``options``, checked by :meth:`check_options`), its criteria (the
  questions asked of a trial's clips), the defaults that depend on the number of sources
  (:meth:`defaults`), and its instructions;
- the stimulus roles a build must make for it (:meth:`stimulus_roles`: catch, practice,
  reference, scoring-standard examples, anchors) and what to do after registration
  (:meth:`after_register`);
- what a trial shows (:meth:`plan_trials`, the clips shown beside the judged ones) and
  asks (its template beside this module, :meth:`item_field`, :meth:`trial_field`);
- how an answer is checked (:meth:`check_answer`), stored (:meth:`item_value`,
  :meth:`trial_value`), graded (:meth:`catch_passed`, :meth:`consistent`) and exported
  (:attr:`export_columns`, :meth:`export_values`);
- its instructed-response checks: a trial whose text says which answer to give
  (:meth:`instruct` picks it, :meth:`instruction_text` says it, :meth:`obeyed` grades it,
  :meth:`obey` gives it, for bots and tests);
- how a simulated participant answers (:meth:`bot_answer`), and for tests the answer
  fields of a valid post (:meth:`answer_fields`) and of a catch trial spotted or missed
  (:meth:`catch_answers`).

Its analysis is the one registered under the same key in ``analysis/``, which also
brings the type's answer column, extra columns and simulated raters. A new type is its
module here, its template here (``<key>.html``) and its analysis module in ``analysis/``;
``tests/test_plugins.py`` fails when anything else names its key.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, field

from studyapp.participation import adaptive, arena, assignment
from studyapp.participation.answers import Criterion
from studyapp.survey.models import Stimulus, Trial, TrialItem
from studyapp.survey.study_type_registry import STUDY_TYPES

registry = STUDY_TYPES

DEFAULT_CONSENT = """\
This study is part of academic research on how people perceive human movement. \
You will watch short, silent animations of a figure moving and answer questions about them. \
It takes about {minutes}.

Taking part is voluntary and you may stop at any time by closing the page. \
We store your answers, the time you took, how the clips were played and the platform id \
you arrived with; we do not ask for your name or any other personal information. \
The anonymous answers may be published for research."""

# Options every type has (Study fields), as a build config names them.
COMMON_OPTIONS = {
    "clips_per_trial": int, "trials_per_participant": int, "practice": bool,
    "catch_trials": int, "instructed_checks": int, "max_failed_catch": int, "repeat_trials": int,
    "ask_demographics": bool, "max_participants": int, "completion_url": str,
    "design": str, "adaptive": dict, "arena": dict, "stop_when": dict,
    "instructions": str, "data_note": str, "criteria": list, "crowd": dict,
}


@dataclass(frozen=True)
class Option:
    """One option of a study type: its type, default and what it does."""

    kind: type
    default: object
    help: str = ""
    choices: tuple = ()


@dataclass(eq=False)
class TrialPlan:
    """One trial to create: its action, the judged stimuli in display order, its kind, the
    stimuli shown beside them (``shown``: ``(stimulus, role, required)``) and, for an
    instructed check, the answer its text asks for (``instruction``).

    Plans compare by identity, so a repeat can point at the plan it repeats.
    """

    action: str
    stimuli: list = field(default_factory=list)
    kind: str = Trial.Kind.MAIN
    repeat_of: "TrialPlan | None" = None
    shown: list = field(default_factory=list)
    instruction: dict = field(default_factory=dict)

    @property
    def prompt(self) -> str:
        return self.stimuli[0].prompt if self.stimuli else ""

    def items(self, trial) -> list[TrialItem]:
        """Return the unsaved items of ``trial``: judged first, then the shown ones."""
        items = [
            TrialItem(trial=trial, stimulus=stimulus, position=position)
            for position, stimulus in enumerate(self.stimuli)
        ]
        for stimulus, role, required in self.shown:
            items.append(TrialItem(trial=trial, stimulus=stimulus, role=role,
                                   position=len(items), required=required))
        return items

    def repeated(self) -> "TrialPlan":
        """Return this trial shown again: clips mirrored (a pair swaps sides); what is shown
        beside them is copied from the original once planned (:meth:`copy_shown`)."""
        return TrialPlan(self.action, self.stimuli[::-1], Trial.Kind.REPEAT, repeat_of=self)

    def copy_shown(self) -> None:
        """Show a repeat with its original's reference and examples (examples no longer
        required: they were seen)."""
        self.shown = [(s, role, role == TrialItem.Role.REFERENCE)
                      for s, role, _ in self.repeat_of.shown]


class StudyType:
    """What differs between study protocols; the flow around it is shared."""

    name = ""
    label = ""
    template = ""  # beside this module; "<key>.html" by default
    scripts: tuple[str, ...] = ("survey/choices.js",)
    # Seconds to give one answer (per judged clip, or per trial for a type with a
    # ``trial_answer``) after the clips played: the estimate of a session's length
    # (:mod:`studyapp.participation.duration`) adds it to the clips' playing time.
    answer_seconds = 4.0
    default_clips_per_trial = 6
    min_items = 2
    max_items: int | None = None
    one_per_source = False  # by default a trial shows one clip of every source
    default_criterion = Criterion("preference")
    options: dict[str, Option] = {}
    item_prefix: str | None = None  # field prefix of each judged clip's answer
    trial_answer: str | None = None  # field name of an answer given on the trial
    export_columns: tuple[str, ...] = ()
    # Words of this type's questions that are also source names ("real" in "real or
    # generated"): allowed on its pages only because every trial page shows them alike.
    interface_words: tuple[str, ...] = ()

    # --- the study ------------------------------------------------------------------

    def template_name(self) -> str:
        return self.template or f"{self.name}.html"

    def default_instructions(self, study) -> str:
        raise NotImplementedError

    def prompt_instructions(self, study) -> str:
        """Return the default instructions of a study whose trials show text prompts."""
        return for_prompts(self.default_instructions(study))

    def default_consent(self, minutes: int) -> str:
        """Return the consent text of a study taking about ``minutes``."""
        return DEFAULT_CONSENT.format(minutes="1 minute" if minutes == 1 else f"{minutes} minutes")

    def answer_time(self, study, n_judged: int) -> float:
        """Return the seconds of answering one trial of ``n_judged`` clips once its clips
        have played: ``answer_seconds`` per clip (per trial with a ``trial_answer``) and
        criterion."""
        answers = 1 if self.trial_answer else n_judged
        return self.answer_seconds * answers * len(self.criteria(study))

    def check_options(self, options: dict) -> dict:
        """Return ``options`` checked against this type's; raise ValueError naming the bad one."""
        if not isinstance(options, dict):
            raise ValueError(f"options: {options!r} must be a mapping")
        out = {}
        for name, value in options.items():
            spec = self.options.get(name)
            if spec is None:
                known = ", ".join(self.options) or "none"
                raise ValueError(f"{name}: not an option of {self.name} studies (its options: "
                                 f"{known})")
            if value is None:
                continue
            if not isinstance(value, spec.kind) or (spec.kind is int and isinstance(value, bool)):
                raise ValueError(f"{name}: {value!r} must be {spec.kind.__name__}")
            if spec.choices and value not in spec.choices:
                raise ValueError(f"{name}: {value!r} is not one of {', '.join(map(str, spec.choices))}")
            out[name] = value
        return out

    def option(self, study, name: str):
        spec = self.options[name]
        return (study.options or {}).get(name, spec.default)

    def criteria(self, study) -> list[Criterion]:
        """Return the questions asked of every trial's clips, the first one first."""
        if not study.criteria:
            return [self.default_criterion]
        return [criterion_of(c) for c in study.criteria]

    def clean_study(self, study) -> dict:
        """Return ``{field: message}`` of what is wrong with ``study`` for this type."""
        errors = {}
        n = self.items_per_trial(study)
        if not self.min_items <= n <= (self.max_items or n):
            most = f" and at most {self.max_items}" if self.max_items else ""
            errors["clips_per_trial"] = (f"A {self.label.lower()} trial shows at least "
                                         f"{self.min_items}{most} clips.")
        try:
            self.check_options(study.options or {})
        except ValueError as exc:
            errors["options"] = str(exc)
        problem = check_criteria(study.criteria)
        if problem:
            errors["criteria"] = problem
        problem = adaptive.check(study.design, study.adaptive, self.name)
        if problem:
            errors["adaptive" if problem.startswith("adaptive") else "design"] = problem
        _, problem = arena.check(study.arena, study.design, adaptive.model(self.name) == "pairs",
                                 study.stop_when)
        if problem:
            errors["arena"] = problem
        problem = adaptive.check_stop(study.stop_when, self.name)
        if problem:
            errors["stop_when"] = problem
        return errors

    def defaults(self, n_sources: int) -> dict:
        """Return study fields whose default depends on the number of sources."""
        return {"clips_per_trial": n_sources} if self.one_per_source else {}

    # --- stimuli --------------------------------------------------------------------

    def stimulus_roles(self, settings: dict) -> dict[str, int]:
        """Return how many clips of each extra role a build makes per action.

        ``settings`` are the study's settings (``catch_trials``, ``practice``,
        ``clips_per_trial``, options). Catch clips are an obviously broken version of a
        real clip; practice clips are kept for the practice trial only (never judged
        later), as many as a trial judges, so the practice looks like the real trials.
        """
        roles = {}
        if settings.get("catch_trials"):
            roles[Stimulus.Role.CATCH] = 1
        if settings.get("practice"):
            shown = settings.get("clips_per_trial") or self.default_clips_per_trial
            roles[Stimulus.Role.PRACTICE] = max(self.min_items, shown, 1)
        return roles

    def after_register(self, study, clips, stimuli) -> None:
        """Finish a study after a build registered ``clips`` as ``stimuli`` (same order)."""

    # --- planning -------------------------------------------------------------------

    def items_per_trial(self, study) -> int:
        return study.clips_per_trial

    def trials_per_action(self, study, table) -> int:
        """Return how many main trials each action gets by default."""
        return 1

    def plan_trials(self, study, rng, tally=None) -> list[TrialPlan]:
        """Return the trials of a new participant; called with the study row locked
        (``tally``: the balance counts the start has read, a
        :class:`~studyapp.survey.models.participation.Tally`).

        Main trials first draw on ``rng`` exactly as a session without extras would,
        so the practice, catch, instructed and repeated trials never change which clips
        a participant judges. Catch and instructed checks are placed alike (never first).
        """
        if study.stop_when and study.design != "adaptive":
            # The stopping rule is checked where the adaptive design is recomputed (an
            # adaptive study asks from its planning); here for every type, whatever
            # planning it brings.
            adaptive.request_recompute(study)
        pool = assignment.Pool.of(study, tally)
        main = self.plan_main(study, pool, rng)
        practice = self.plan_practice(study, pool, rng) if study.practice else None
        if practice and main:  # no more clips than the trials show (fewer sources than k)
            practice.stimuli = practice.stimuli[:max(len(plan.stimuli) for plan in main)]
        catch = [
            plan
            for stimulus in assignment.pick_catch(pool.catches, study.catch_trials, rng)
            if (plan := self.plan_catch(study, pool, stimulus, rng)) is not None
        ]
        for _ in range(study.instructed_checks if main else 0):
            plan = self.plan_instructed(study, pool, rng)
            if plan is not None:
                plan.instruction = self.instruct(study, len(plan.stimuli), rng)
                catch.append(plan)
        session = assignment.arrange(main, catch, study.repeat_trials, rng)
        plans = ([practice] if practice else []) + session
        self.add_shown(study, pool, [p for p in plans if p.repeat_of is None], rng)
        for plan in plans:
            if plan.repeat_of is not None:
                plan.copy_shown()
        return plans

    def plan_main(self, study, pool, rng) -> list[TrialPlan]:
        """Return balanced main trials: the least-judged stimuli, sources over positions;
        in an adaptive study, pairs drawn from its stored distribution when there is one."""
        if study.design == "adaptive":
            drawn = adaptive.plan_main(study, pool, rng)
            if drawn is not None:
                return [TrialPlan(action, seats) for action, seats in drawn]
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
        """Return a practice trial of the clips kept for practice (never judged later)."""
        by_action = {}
        for stimulus in pool.practice:
            by_action.setdefault(stimulus.action, []).append(stimulus)
        if not by_action:
            return None
        action = rng.choice(sorted(by_action))
        stimuli = rng.sample(by_action[action], len(by_action[action]))[: self.items_per_trial(study)]
        if len(stimuli) < self.min_items:
            return None
        return TrialPlan(action, stimuli, Trial.Kind.PRACTICE)

    def plan_catch(self, study, pool, stimulus, rng) -> TrialPlan | None:
        """Return a trial showing the broken clip ``stimulus`` among clips of its action."""
        fill = assignment.choose_balanced(
            pool.table.get(stimulus.action, {}), Counter(), rng, self.items_per_trial(study) - 1
        )
        if len(fill) + 1 < self.min_items:
            return None
        # Seated as main trials are (sources over positions), so catch trials do not
        # unbalance where each source is shown.
        stimuli = assignment.order_positions(fill + [stimulus], pool.positions, rng)
        for position, seated in enumerate(stimuli):
            pool.positions[(seated.source, position)] += 1
        return TrialPlan(stimulus.action, stimuli, Trial.Kind.CATCH)

    def plan_instructed(self, study, pool, rng) -> TrialPlan | None:
        """Return a trial of judged clips of one action for an instructed check (its
        instruction is added by :meth:`instruct`); it looks like any other trial."""
        actions = sorted(pool.table)
        if not actions:
            return None
        action = rng.choice(actions)
        chosen = assignment.choose_balanced(pool.table[action], Counter(), rng,
                                            self.items_per_trial(study))
        if len(chosen) < self.min_items:
            return None
        stimuli = assignment.order_positions(chosen, pool.positions, rng)
        for position, seated in enumerate(stimuli):
            pool.positions[(seated.source, position)] += 1
        return TrialPlan(action, stimuli, Trial.Kind.INSTRUCTED)

    def add_shown(self, study, pool, plans, rng) -> None:
        """Add the clips shown beside the judged ones (a reference, examples) to ``plans``
        (every plan but repeats, which show what their original showed)."""

    # --- the trial page -------------------------------------------------------------

    def item_label(self, item) -> str:
        """Return the name a participant sees for a judged clip ("Clip A")."""
        return clip_label(item.position)

    def trial_context(self, study, trial, items) -> dict:
        """Return extra template context for the trial page."""
        return {}

    def instruction_sentence(self, study, trial, judged) -> str:
        """Return what an instructed check's page says (the first criterion's answer)."""
        text = self.instruction_text(study, trial.instruction, judged)
        criteria = self.criteria(study)
        if len(criteria) > 1:
            text += f" (in the question \u201c{criteria[0].text}\u201d)"
        return f"This is an attention check: {text}"

    def item_field(self, study, item, label: str, n_items: int):
        """Return the form field of one judged clip's answer (prefix ``item_prefix``)."""
        return None

    def trial_field(self, study, judged):
        """Return the form field of an answer on the trial itself (name ``trial_answer``)."""
        return None

    def check_answer(self, study, values: dict, judged) -> str | None:
        """Return what is wrong with one criterion's answers ``{item: value}``, or None."""
        return None

    def item_value(self, value):
        """Return what is stored of a judged clip's cleaned answer."""
        return value

    def trial_value(self, value, judged):
        """Return what is stored of the trial's cleaned answer."""
        return value

    # --- grading --------------------------------------------------------------------

    def grade(self, trial, items) -> bool | None:
        """Return whether a catch trial was passed or a repeat answered as before.

        Only the first criterion is graded (a broken clip is broken on every criterion).
        """
        study = trial.participant.study
        key = self.criteria(study)[0].key
        judged = [item for item in items if item.role == TrialItem.Role.JUDGED]
        if trial.kind == Trial.Kind.CATCH:
            return self.catch_passed(Graded(trial, judged, key))
        if trial.kind == Trial.Kind.INSTRUCTED:
            return self.obeyed(Graded(trial, judged, key), trial.instruction)
        if trial.kind == Trial.Kind.REPEAT and trial.repeat_of_id:
            before = trial.repeat_of
            earlier = list(before.items.filter(role=TrialItem.Role.JUDGED).select_related("stimulus"))
            return self.consistent(Graded(before, earlier, key), Graded(trial, judged, key))
        return None

    def catch_passed(self, answered: "Graded") -> bool:
        """Return whether the answer treats the broken clip as the worst."""
        raise NotImplementedError

    def consistent(self, before: "Graded", now: "Graded") -> bool:
        """Return whether a repeated trial got the same answer as the trial it repeats."""
        raise NotImplementedError

    # --- instructed-response checks ------------------------------------------------
    # An instruction is a small mapping; ``position`` (when it has one) names the clip it
    # is about. Two different instructions about the same clip (or without a clip)
    # never accept the same answer, so an answer given to another one always fails.

    def instruct(self, study, n_judged: int, rng) -> dict:
        """Return the answer an instructed check of ``n_judged`` clips asks for (stored
        in ``Trial.instruction``), drawn with ``rng``; it says nothing of the clips."""
        raise NotImplementedError

    def instruction_text(self, study, instruction: dict, judged) -> str:
        """Return the words telling the participant exactly which answer to give
        (``judged``: the trial's judged items in screen order)."""
        raise NotImplementedError

    def obeyed(self, answered: "Graded", instruction: dict) -> bool:
        """Return whether the answer is the one ``instruction`` asked for."""
        raise NotImplementedError

    def obey(self, page, instruction: dict, answer: dict) -> dict:
        """Return ``answer`` (the first criterion's fields, as :meth:`bot_answer` gives
        them) changed to give what ``instruction`` asks; ``page.tokens`` are the judged
        clips in screen order."""
        raise NotImplementedError

    # --- export ---------------------------------------------------------------------

    def export_values(self, trial_answer, item_answer, item: dict, items: list) -> dict:
        """Return the export columns of one judged clip for one criterion.

        ``trial_answer`` / ``item_answer`` are the stored values of that criterion (None
        when not answered); ``item`` and ``items`` (the trial's judged items) are dicts
        with ``position`` and ``stimulus``.
        """
        return {}

    # --- bots -----------------------------------------------------------------------

    def answer_fields(self, items, **given) -> dict:
        """Return the answer fields of a valid post for a trial, for tests.

        ``items`` are the trial's items in screen order (``position``, ``token``, ``role``);
        ``given`` holds answers by this type's own keywords (positions to values, or the
        trial's one answer), defaults where absent; keywords of other types are ignored.
        """
        raise NotImplementedError

    def catch_answers(self, position: int) -> tuple[dict, dict]:
        """Return two answers to a catch trial whose broken clip is at ``position``, as
        :meth:`answer_fields` keywords: one that spots the broken clip and one that does
        not (for tests)."""
        raise NotImplementedError

    def bot_answer(self, page, policy) -> dict:
        """Return the answer fields (first criterion's names) a bot posts for a trial.

        ``page.tokens`` are the judged clips in screen order, ``page.sources`` their
        sources (looked up in the database, never read from the page).
        """
        raise NotImplementedError


@dataclass
class Graded:
    """One criterion's answers of an answered trial, for grading."""

    trial: Trial
    items: list
    key: str

    @property
    def choice(self):
        return (self.trial.answers or {}).get(self.key)

    def value(self, item):
        return (item.answers or {}).get(self.key)

    def at(self, position: int):
        """Return the judged item at ``position`` (an instructed check's clip)."""
        return next(item for item in self.items if item.position == position)

    def catch(self):
        """Return the broken clip of a catch trial."""
        return next(item for item in self.items if item.stimulus.role == Stimulus.Role.CATCH)

    def by_stimulus(self) -> dict:
        return {item.stimulus_id: item for item in self.items}


# How the default instructions speak of a trial's action, and of a text prompt instead.
PROMPT_WORDING = (
    ('names an action, for example "walk", and shows',
     'shows a short text, for example "a person walks forward and waves", and'),
    ("of a figure performing it", "of a figure moving"),
    ("shows the named action", "matches the text"),
    ("the named action", "the text"),
)


def for_prompts(text: str) -> str:
    """Return instructions written for actions reworded for text prompts."""
    for before, after in PROMPT_WORDING:
        text = text.replace(before, after)
    return text


def scores_consistent(before: "Graded", now: "Graded", max_change) -> bool:
    """Whether no clip's score in ``now`` moved by more than ``max_change`` from ``before``
    (a repeated trial of a type that scores each clip)."""
    earlier = before.by_stimulus()
    return all(abs(now.value(item) - before.value(earlier[item.stimulus_id])) <= max_change
               for item in now.items)


def judged_at(judged, position: int):
    """Return the item of ``judged`` shown at ``position``."""
    return next(item for item in judged if item.position == position)


def clip_label(position: int) -> str:
    """Return the name a participant sees for the clip at ``position`` ("Clip A")."""
    letters = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    name = letters[position % 26] * (position // 26 + 1)
    return f"Clip {name}"


def criterion_of(entry) -> Criterion:
    """Return the :class:`Criterion` of one entry of a study's ``criteria``: a mapping
    ``{key, question}``, or a text such as ``fit to the action`` (key ``fit_to_the_action``,
    shown as written, first letter capitalised)."""
    if isinstance(entry, str):
        words = " ".join(entry.split())
        key = re.sub(r"[^a-z0-9]+", "_", words.lower()).strip("_")
        return Criterion(key, words[:1].upper() + words[1:])
    return Criterion(entry["key"], entry.get("question", ""))


def check_criteria(criteria) -> str | None:
    """Return what is wrong with a study's ``criteria`` list, or None."""
    if not criteria:
        return None
    if not isinstance(criteria, list):
        return ("criteria must be a list of questions, e.g. [naturalness, fit to the action] "
                "or [{key: naturalness, question: How natural is the movement?}]")
    keys = []
    for i, c in enumerate(criteria):
        if isinstance(c, str):
            key = criterion_of(c).key
            if not re.fullmatch(r"[a-z][a-z0-9_]{0,29}", key):
                return (f"criteria.{i}: {c!r} must start with a letter and make a key of at "
                        f"most 30 letters, digits and underscores (it makes {key!r}); or give "
                        f"{{key: short_name, question: ...}}")
            keys.append(key)
            continue
        if not isinstance(c, dict) or set(c) - {"key", "question"}:
            return f"criteria.{i}: give key and question, e.g. {{key: naturalness, question: ...}}"
        key = c.get("key")
        if not isinstance(key, str) or not re.fullmatch(r"[a-z][a-z0-9_]{0,29}", key):
            return f"criteria.{i}.key: {key!r} must be a short snake_case name"
        if not isinstance(c.get("question", ""), str):
            return f"criteria.{i}.question: must be text"
        keys.append(key)
    if len(set(keys)) != len(keys):
        twice = next(k for k in keys if keys.count(k) > 1)
        return f"criteria: the key {twice!r} is used twice; each question needs its own key"
    return None
