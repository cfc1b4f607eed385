"""The adaptive design's sampling distribution, recomputed from a study's answers so far
(the ``adaptive_design`` command, run in the background: see
:mod:`studyapp.participation.adaptive`)."""

from __future__ import annotations

import numpy as np
from django.utils import timezone

from analysis import adaptive
from analysis.registry import get_analysis
from analysis.study import apply_exclusions
from analysis.tables import AnalysisError
from studyapp.participation.adaptive import answered_main, settings
from studyapp.participation.assignment import stimuli_by_action
from studyapp.results.export import responses_frame
from studyapp.survey.models import Study


def recompute(study) -> dict:
    """Fit the posterior to the study's answers so far and store the distribution."""

    names = sorted({source for by_source in stimuli_by_action(study).values() for source in by_source})
    answers = answered_main(study)
    winner, loser, weight = [], [], []
    table = responses_frame(study)
    if len(table) and "criterion" in table.columns:
        table = table.loc[table["criterion"] == table["criterion"].iloc[0]]
    if len(table):
        try:
            main, _, _ = apply_exclusions(table, study_type=study.study_type)
        except AnalysisError:  # nothing analysable yet: a posterior of the prior alone
            main = None
        decided = get_analysis(study.study_type).worth_comparisons(main) if main is not None and len(main) else None
        if decided is not None and len(decided):
            index = {name: i for i, name in enumerate(names)}
            known = decided["winner"].isin(index) & decided["loser"].isin(index)
            decided = decided.loc[known]
            winner = decided["winner"].map(index).to_numpy()
            loser = decided["loser"].map(index).to_numpy()
            weight = decided["weight"].to_numpy(float)
    chosen = settings(study)
    post = adaptive.posterior(len(names), winner, loser, weight if len(weight) else None)
    target, note = chosen["target"], ""
    if isinstance(target, dict):
        if target["versus"] in names:
            target = adaptive.versus(len(names), names.index(target["versus"]))
        else:
            note = f"no source {target['versus']!r} in the study: aimed at the order instead"
            target = "order"
    dist = adaptive.distribution(post, target, floor=chosen["floor"], sharpness=chosen["sharpness"],
                                 focus=chosen["focus"], seed=answers)
    sampling = {"sources": names, **dist, "answers": answers, "comparisons": len(winner),
                "worth": np.round(post.mean, 4).tolist(), "computed_at": timezone.now().isoformat(),
                **({"note": note} if note else {})}
    Study.objects.filter(pk=study.pk).update(sampling=sampling)
    study.sampling = sampling
    return sampling


