"""Adaptive designs in the app: the stored sampling distribution, its recomputation in
the background, and main trials planned from it.

A study with ``design: adaptive`` (of a type whose analysis has a worth model of pairs,
:meth:`analysis.registry.StudyAnalysis.worth_comparisons`) keeps in ``Study.sampling`` a
distribution over pairs of its sources (:func:`analysis.adaptive.distribution`), or over sets of its sources for types whose
analysis has a Plackett-Luce model of choices (:meth:`StudyAnalysis.worth_choices`:
:func:`analysis.adaptive.set_distribution`). It is recomputed by the ``adaptive_design``
command, run as a background job when a new participant starts and at least ``every``
main trials were answered since it was last computed or asked for: never in the answer
path. Until one is stored the study plans balanced trials, as a balanced study does. The
same job checks a study's stopping rule (``Study.stop_when``, any design; :func:`check_stop`).
"""

from __future__ import annotations

from django.db import transaction

from analysis import adaptive
from analysis.registry import StudyAnalysis, get_analysis
from studyapp.survey.models import Study, Trial

# How the recomputation starts in the background: ``run_job(kind, **params)``, set to
# ``survey.tasks.run_job`` by the survey app's ``ready`` (passed in, so that this module,
# which the study types' planning imports, imports no job runner).
run_job = None

DEFAULTS = {"every": 50, "min_showings": 2, "target": "order", "floor": adaptive.FLOOR,
            "sharpness": 2.0, "focus": 2.0, "batch": None}
DESIGNS = ("balanced", "adaptive")


def model(study_type: str) -> str | None:
    """Return the worth model a study type's analysis offers an adaptive design: ``"pairs"``
    (Bradley-Terry, :meth:`StudyAnalysis.worth_comparisons`), ``"sets"`` (Plackett-Luce
    choices among the trial's sources, :meth:`StudyAnalysis.worth_choices`) or None."""
    kind = type(get_analysis(study_type))
    if kind.worth_comparisons is not StudyAnalysis.worth_comparisons:
        return "pairs"
    if kind.worth_choices is not StudyAnalysis.worth_choices:
        return "sets"
    return None


def supports(study_type: str) -> bool:
    """Return whether a study type's analysis has the worth model an adaptive design needs."""
    return model(study_type) is not None


def settings(study) -> dict:
    """Return a study's adaptive settings, the defaults filled in. ``batch`` left out: for
    pairs aimed at the whole order, the comparisons up to the next look (``every``) are
    planned as one batch (simulated with a look and a batch every 100 judgements: 33 %
    fewer judgements than balanced by the app's rule, 24 % without batches;
    docs/BENCHMARKS.md); otherwise none. Arenas are not batched unless asked: their
    benchmark (a new source brought to precision) was run without batches."""
    chosen = {**DEFAULTS, **(study.adaptive or {})}
    if chosen["batch"] is None:
        batched = (chosen["target"] == "order" and model(study.study_type) == "pairs"
                   and not study.arena)
        chosen["batch"] = chosen["every"] if batched else 0
    return chosen


def check(design, given, study_type: str) -> str | None:
    """Return what is wrong with a design and its settings for a study type, or None."""
    if design not in DESIGNS:
        return f"design: {design!r} is not one of {', '.join(DESIGNS)}"
    if design == "balanced":
        return None
    if not supports(study_type):
        return (f"design: adaptive needs a type with a worth model (of pairs, or of choices "
                f"among a trial's sources); {study_type} has none")
    if not isinstance(given or {}, dict):
        return f"adaptive: {given!r} must be a mapping like {{every: 50, min_showings: 2}}"
    for name, value in (given or {}).items():
        if name not in DEFAULTS:
            return f"adaptive.{name}: not a setting (settings: {', '.join(DEFAULTS)})"
        if name in ("every", "min_showings", "batch") and (
                not isinstance(value, int) or isinstance(value, bool) or value < (1 if name == "every" else 0)):
            return f"adaptive.{name}: {value!r} must be a whole number of at least {1 if name == 'every' else 0}"
        if name == "batch" and value and model(study_type) != "pairs":
            return (f"adaptive.batch: batches are planned for pairs of sources only; {study_type} "
                    f"draws sets (leave batch out)")
        if name == "floor" and not (isinstance(value, (int, float)) and 0 < value <= 1):
            return f"adaptive.floor: {value!r} must be in (0, 1]"
        if name in ("sharpness", "focus") and not (isinstance(value, (int, float)) and value >= 0):
            return f"adaptive.{name}: {value!r} must be 0 or more"
        if name == "target" and value not in ("order", "top_two") and not (
                isinstance(value, dict) and set(value) == {"versus"} and isinstance(value["versus"], str)):
            return (f"adaptive.target: {value!r} must be order, top_two or {{versus: <source>}} "
                    f"(that source against each other)")
    return None


def check_stop(stop_when, study_type: str) -> str | None:
    """Return what is wrong with a stopping rule ``stop_when`` for a study type, or None.

    ``{interval_width: W}``: the widest 95 % interval of the target's differences (the
    top two, every neighbour in the order, or each ``versus`` difference; logit scale) is
    at most ``W``; ``{rank_certainty: P}``: the posterior probability that the target's
    estimated order is right is at least ``P``; ``{judgements: N}``: ``N`` answered main
    trials. Several: the first met stops. The first two need a worth model."""
    if not stop_when:
        return None
    example = "{interval_width: 0.6}, {rank_certainty: 0.95} or {judgements: 2000}"
    if not isinstance(stop_when, dict):
        return f"stop_when: {stop_when!r} must be a mapping like {example}"
    for name, value in stop_when.items():
        if name not in adaptive.STOP_RULES:
            return (f"stop_when.{name}: not a stopping rule (rules: "
                    f"{', '.join(adaptive.STOP_RULES)}), e.g. {example}")
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if name == "interval_width" and not (number and value > 0):
            return f"stop_when.interval_width: {value!r} must be a width above 0 (logit scale), e.g. 0.6"
        if name == "rank_certainty" and not (number and 0.5 <= value < 1):
            return f"stop_when.rank_certainty: {value!r} must be a probability in [0.5, 1), e.g. 0.95"
        if name == "judgements" and not (isinstance(value, int) and not isinstance(value, bool)
                                         and value >= 1):
            return f"stop_when.judgements: {value!r} must be a whole number of answered trials, at least 1"
        if name != "judgements" and not supports(study_type):
            return (f"stop_when.{name}: needs a type with a worth model (of pairs, or of choices "
                    f"among a trial's sources); {study_type} has none: stop it by "
                    f"judgements instead")
    return None


def answered_main(study) -> int:
    return Trial.objects.filter(participant__study=study, kind=Trial.Kind.MAIN,
                                answered_at__isnull=False).count()


def request_recompute(study) -> bool:
    """Start the recomputation in the background when ``every`` main trials were answered
    since the last one (computed or asked for); called with the study row locked. A study
    its stopping rule closed asks no more while closed; opened again by its staff, its
    design is recomputed again (the rule, already met, does not close it twice)."""
    if study.stopped and study.status != study.Status.OPEN:
        return False
    stored = study.sampling or {}
    last = max(stored.get("answers", -1), stored.get("requested", -1))
    answers = answered_main(study)
    budget = (study.stop_when or {}).get("judgements")
    over_budget = budget is not None and answers >= budget and last < budget
    if last >= 0 and answers - last < settings(study)["every"] and not over_budget:
        return False
    stored = {**stored, "requested": answers}
    Study.objects.filter(pk=study.pk).update(sampling=stored)
    study.sampling = stored
    if run_job is not None:
        transaction.on_commit(lambda: run_job("call_command", name="adaptive_design",
                                              args=[study.slug]))
    return True


def plan_main(study, pool, rng):
    """Return main trials ``(action, [stimuli in their seats])`` drawn from the stored
    distribution (of pairs, or of sets of sources), or None when none is stored (the
    caller then plans balanced trials)."""
    request_recompute(study)
    stored = study.sampling or {}
    if not (stored.get("pairs") or stored.get("sets")):
        return None
    names = stored["sources"]
    clips, action_of = {}, {}
    for action, by_source in pool.table.items():
        for source, stimuli in by_source.items():
            if source in names:
                for stimulus in stimuli:
                    clips.setdefault(names.index(source), []).append(stimulus.pk)
                    action_of[stimulus.pk] = action
    if not clips:
        return None
    stimuli = {s.pk: s for by_source in pool.table.values() for ss in by_source.values() for s in ss}
    wanted = study.trials_per_participant or len(pool.table)
    plan = adaptive.plan_sets if stored.get("sets") else adaptive.plan_pairs
    trials = plan(stored, wanted, clips, pool.items, rng,
                  min_showings=settings(study)["min_showings"], group_of=action_of.__getitem__)
    plans = []
    for trial in trials:
        seats = [stimuli[pk] for pk in trial]
        for position, stimulus in enumerate(seats):
            pool.positions[(stimulus.source, position)] += 1
        plans.append((action_of[trial[0]], seats))
    return plans
