"""The adaptive design's sampling distribution, recomputed from a study's answers so far
(the ``adaptive_design`` command, run in the background: see
:mod:`studyapp.participation.adaptive`)."""

from __future__ import annotations

import numpy as np
from django.db import transaction
from django.utils import timezone

from analysis import adaptive
from analysis.registry import get_analysis
from analysis.study import apply_exclusions
from analysis.tables import AnalysisError
from studyapp.participation.adaptive import answered_main, model, settings
from studyapp.participation.assignment import stimuli_by_action
from studyapp.results.export import responses_frame
from studyapp.survey.models import Study


def main_rows(study):
    """Return the answered main rows the analysis would keep (of the first criterion), or
    None when there is nothing analysable yet."""
    table = responses_frame(study)
    if len(table) and "criterion" in table.columns:
        table = table.loc[table["criterion"] == table["criterion"].iloc[0]]
    if not len(table):
        return None
    try:
        main, _, _ = apply_exclusions(table, study_type=study.study_type)
    except AnalysisError:  # nothing analysable yet: a posterior of the prior alone
        return None
    return main if len(main) else None


def fit(study, names, main=None):
    """Return the study's worth posterior over ``names`` (the prior alone without answers),
    the number of comparisons or choices it rests on, and the spread of its differences
    (:class:`analysis.adaptive.Spread`: clips and participants counted where the type's
    comparisons name them)."""
    kind = model(study.study_type)
    analysis = get_analysis(study.study_type)
    index = {name: i for i, name in enumerate(names)}
    if kind == "sets":
        chosen, among, weight = [], [], []
        clips = None
        decided = analysis.worth_choices(main) if main is not None else None
        if decided is not None and len(decided):
            known = decided["among"].map(lambda members: all(m in index for m in members))
            decided = decided.loc[known.to_numpy(bool)]
            chosen = decided["chosen"].map(index).to_numpy()
            among = [[index[m] for m in members] for members in decided["among"]]
            weight = decided["weight"].to_numpy(float)
            if {"among_clips", "participant"} <= set(decided.columns):
                clips = (list(decided["among_clips"]), decided["participant"].to_numpy())
        post = adaptive.choice_posterior(len(names), chosen, among, weight if len(weight) else None)
        spread = adaptive.choice_spread(post, chosen, among, *(clips or ()),
                                        weight=weight if clips else None)
        return post, len(chosen), spread
    winner, loser, weight = [], [], []
    clips = None
    decided = analysis.worth_comparisons(main) if main is not None else None
    if decided is not None and len(decided):
        known = decided["winner"].isin(index) & decided["loser"].isin(index)
        decided = decided.loc[known]
        winner = decided["winner"].map(index).to_numpy()
        loser = decided["loser"].map(index).to_numpy()
        weight = decided["weight"].to_numpy(float)
        if {"winner_clip", "loser_clip", "participant"} <= set(decided.columns):
            clips = (decided["winner_clip"].to_numpy(), decided["loser_clip"].to_numpy(),
                     decided["participant"].to_numpy())
    post = adaptive.posterior(len(names), winner, loser, weight if len(weight) else None)
    return post, len(winner), adaptive.spread(post, winner, loser, *(clips or ()))


def target_of(study, names):
    """Return the contrasts' target of the study's settings and a note when a named source
    is missing."""
    target = settings(study)["target"]
    if isinstance(target, dict):
        if target["versus"] in names:
            return adaptive.versus(len(names), names.index(target["versus"])), ""
        return "order", f"no source {target['versus']!r} in the study: aimed at the order instead"
    return target, ""


def recompute(study) -> dict:
    """Fit the posterior to the study's answers so far, store the distribution (an
    adaptive study) and check the stopping rule (any study with one): met, the study
    stops (:func:`stop`)."""

    names = sorted({source for by_source in stimuli_by_action(study).values() for source in by_source})
    answers = answered_main(study)
    post, decided, spread = fit(study, names, main_rows(study))
    chosen = settings(study)
    target, note = target_of(study, names)
    options = dict(floor=chosen["floor"], sharpness=chosen["sharpness"], focus=chosen["focus"],
                   seed=answers)
    dist = {}
    if study.design == "adaptive" and model(study.study_type) == "sets":
        size = min(study.kind.items_per_trial(study), len(names))
        dist = adaptive.set_distribution(post, size, target,
                                         depth=get_analysis(study.study_type).choice_depth, **options)
    elif study.design == "adaptive":
        dist = adaptive.distribution(post, target, batch=chosen["batch"], **options)
    sampling = {"sources": names, **dist, "batch": chosen["batch"] if dist else 0,
                "answers": answers, "comparisons": decided,
                "worth": np.round(post.mean, 4).tolist(), "computed_at": timezone.now().isoformat(),
                **({"note": note} if note else {})}
    if study.stop_when and len(names) >= 2:
        state = adaptive.stop_state(post, study.stop_when, target, answers, spread, seed=answers)
        sampling["stop"] = state
        if state["met"] and not study.stopped:
            stop(study, state, names)
    Study.objects.filter(pk=study.pk).update(sampling=sampling)
    study.sampling = sampling
    return sampling


def stop(study, state: dict, names) -> dict:
    """Close ``study``'s places because its stopping rule ``state["met"]`` holds, ask its
    crowd platform to send no more people, and record how it stopped (``Study.stopped``)
    for the report. Those taking part may still finish; their answers count."""
    record = {"rule": state["met"], "value": study.stop_when[state["met"]],
              "stop_when": study.stop_when, "judgements": state["judgements"],
              "width": state["width"], "certainty": state["certainty"],
              "interval": state["interval"], "target": settings(study)["target"],
              "pairs": [[names[a], names[b]] for a, b in state["pairs"]],
              "design": study.design, "at": timezone.now().isoformat()}
    with transaction.atomic():
        locked = Study.objects.lock(study.pk)
        if locked.stopped:
            study.stopped = locked.stopped
            return locked.stopped
        Study.objects.filter(pk=study.pk).update(status=Study.Status.CLOSED, stopped=record)
    record["platform"] = study.platform.stop_recruiting(study)
    Study.objects.filter(pk=study.pk).update(stopped=record)
    study.status, study.stopped = Study.Status.CLOSED, record
    return record
