"""The analysis of each study type, in a registry keyed like the survey app's study types.

A study type's analysis subclasses :class:`StudyAnalysis` and registers with
``@register_analysis("key")``; :func:`analysis.study.analyse` applies the shared steps
(checks, exclusions, agreement, repeat consistency) and calls it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import pandas as pd

from analysis.tables import AnalysisError
from motion.registry import Registry

# Every module of the ``analysis`` package is imported before the first lookup: each
# study type's analysis module registers itself, so a new type needs no list here.
ANALYSES = Registry("analysis", package="analysis")


@dataclass
class Table:
    """A result table: ``name`` is its file stem, ``title`` its caption."""

    name: str
    title: str
    frame: pd.DataFrame
    note: str = ""


@dataclass
class Plot:
    """A figure drawn on demand: ``draw()`` returns a matplotlib ``Figure``."""

    name: str
    title: str
    draw: Callable


@dataclass(frozen=True)
class AnswerOption:
    """Answers a study type's option adds: their values (in the type's answer column),
    the phrase the design gets when they were offered, and ``words`` the methods
    paragraph must not use when they were not (lower case)."""

    answers: tuple[str, ...]
    design: str
    words: tuple[str, ...]


@dataclass
class Analysis:
    """What a study type's analysis returns.

    ``sources`` is indexed by source, best first, with ``score``, ``ci_low``,
    ``ci_high``, ``n_participants`` and ``n_judgements``; ``methods`` are sentences for
    the methods paragraph; ``headline`` are short result sentences.
    """

    measure: str
    sources: pd.DataFrame
    tables: list[Table] = field(default_factory=list)
    plots: list[Plot] = field(default_factory=list)
    methods: list[str] = field(default_factory=list)
    headline: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    tests: dict = field(default_factory=dict)


class StudyAnalysis:
    """How one study type's judgements are checked and analysed.

    ``answer`` is the response column holding the answer; ``agreement_level`` the
    Krippendorff level matching it; ``design`` a phrase for the methods paragraph;
    ``extra_columns`` the columns this type's table holds beyond
    :data:`analysis.tables.RESPONSE_COLUMNS` (as the export adds them); ``mixed_model``
    the model of :mod:`analysis.mixed` its analysis fits beside the bootstrap when asked
    (``"linear"`` scores, ``"logistic"`` yes/no answers, ``"worth"`` Bradley-Terry on
    the pairs its answers imply; ``""`` none).

    The ``simulated_*`` hooks make :func:`analysis.simulate.simulate` write this type's
    tables; a type without ``simulated_answers`` cannot be simulated.
    """

    name = ""
    answer = ""
    agreement_level = "nominal"
    design = ""
    extra_columns: tuple[str, ...] = ()
    # The type's options (``Study.options``) that offer answers of their own: option ->
    # ``AnswerOption`` (the answer values it adds, the words that describe them). The
    # methods paragraph names those answers only when the study offered them.
    answer_options: dict = {}
    mixed_model = ""

    def worth_comparisons(self, rows: pd.DataFrame) -> pd.DataFrame | None:
        """Return the decided comparisons of answered main ``rows`` as ``winner`` and
        ``loser`` source columns (and ``weight``; optionally ``winner_clip``,
        ``loser_clip`` and ``participant``, with which a stopping rule's intervals count
        clips and participants as random), for a Bradley-Terry posterior; None when
        this type has no worth model of pairs (then it offers no adaptive design,
        :mod:`analysis.adaptive`)."""
        return None

    # How many Luce choices one trial's answer makes (:meth:`worth_choices`): 1 for a pick
    # of the best, None for a ranking of all the trial's clips (``k - 1`` choices).
    choice_depth: int | None = 1

    def worth_choices(self, rows: pd.DataFrame) -> pd.DataFrame | None:
        """Return the Luce choices of answered main ``rows``: ``chosen`` (a source),
        ``among`` (a tuple of the sources it was chosen among, itself included) and
        ``weight`` (optionally ``among_clips``, the clips of ``among`` in its order, and
        ``participant``, with which a stopping rule's intervals count clips and
        participants as random), for a Plackett-Luce posterior over sets of sources; None
        when this type has no such model (then its adaptive design, if any, is of pairs,
        :meth:`worth_comparisons`)."""
        return None

    def answered(self, rows: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
        """Return the rows with a valid answer and notes on those left out."""
        raise NotImplementedError

    def judgement_values(self, rows: pd.DataFrame) -> pd.DataFrame:
        """Return ``participant``, ``unit``, ``value``: what was judged and the answer given.

        Agreement compares values of one unit across participants; repeat trials
        compare them within a participant.
        """
        frame = rows[["pcode", "stimulus", self.answer]]
        return frame.set_axis(["participant", "unit", "value"], axis=1)

    def describe(self, rows: pd.DataFrame, config) -> str:
        """Return the phrase of the methods paragraph saying what a trial showed and asked,
        for what this study did: the study type's options (``config.type_options``) and,
        when a table comes without them, the answers given (:func:`offered`). Never a
        choice the participants did not have. Default: :attr:`design`, plus the phrase of
        each of :attr:`answer_options` that was offered."""
        text = self.design
        for option, spec in self.answer_options.items():
            seen = (self.answer in rows.columns
                    and rows[self.answer].astype(str).isin(spec.answers).any())
            if offered(config, option, seen):
                text += spec.design
        return text

    def screen(self, rows: pd.DataFrame, config) -> tuple[pd.DataFrame, list[dict], list[str]]:
        """Return the answered main-trial rows kept by this type's own screening rules,
        one exclusion record per rule (``rule``, ``applied`` ``"yes"`` or why not,
        ``participants``, ``trials``, ``judgements`` removed) and notes. Applied only
        when ``config.exclusions``; counted always. Default: no rules."""
        return rows, [], []

    def analyse(self, rows: pd.DataFrame, config) -> Analysis:
        raise NotImplementedError

    # --- simulated raters (analysis.simulate) -------------------------------------------

    def simulated_sources(self, names, strength):
        """Return the names and log-strengths of the sources a simulated trial draws from:
        the given ones, and any controls this type shows as sources of their own."""
        return names, strength

    def simulated_trials(self, rng, n_trials: int, n_sources: int, clips_per_trial: int):
        """Return ``(n_trials, m)`` indices of the sources each simulated trial shows."""
        raise NotImplementedError

    def simulated_answers(self, raters) -> dict:
        """Return this type's answer columns for the rows of
        :class:`analysis.simulate.Raters` (one value per row)."""
        raise NotImplementedError

    def simulated_roles(self, is_catch, row_source, n_sources):
        """Return the ``stimulus_role`` of each simulated row (one for all: ``judged``)."""
        return "judged"


def offered(config, option: str, seen: bool) -> bool:
    """Return whether the study offered what its type's ``option`` switches on: the study's
    own option when the analysis has it (``config.type_options``), else whether any answer
    used it (``seen``): a table analysed without its study says only what happened."""
    options = getattr(config, "type_options", None) or {}
    return bool(options[option]) if option in options else bool(seen)


def register_analysis(name: str):
    """Register a :class:`StudyAnalysis` subclass under the study type ``name``."""
    return ANALYSES.register(name)


def get_analysis(name: str) -> StudyAnalysis:
    """Return an instance of the analysis class registered for study type ``name``."""
    if name not in ANALYSES:
        raise AnalysisError(
            f"no analysis for study type {name!r}; known types: {', '.join(list_analyses())}"
        )
    return ANALYSES.get(name)()


def list_analyses() -> list[str]:
    return ANALYSES.names()
