"""Mixed models with crossed random intercepts for participants and clips (statsmodels).

Reported beside the crossed bootstrap (:mod:`analysis.crossed`) where a maintained
library fits the model, so that each checks the other:

- scores (ratings 1-5, MUSHRA 0-100): a linear mixed model ``y ~ source`` with random
  intercepts per participant and per clip, crossed (statsmodels ``MixedLM`` with
  variance components over one group, REML); differences of source means are Wald tests;
- judged real (fake or real): a logistic mixed model with the same crossed intercepts
  (statsmodels ``BinomialBayesMixedGLM``, variational Bayes), each source against the
  real clips on the log-odds scale.

Their fits take seconds, so they run when the analysis asks (``mixed_models``); a table
too large for their dense design matrices is skipped with a note.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from analysis.registry import Table
from analysis.stats import holm

# Largest rows x (participants + clips) a fit may build (dense random-effects design).
MAX_DESIGN = 20_000_000


def _frame(rows: pd.DataFrame, value: str) -> pd.DataFrame:
    return pd.DataFrame({
        "y": rows[value].to_numpy(dtype=float),
        "source": rows["source"].astype(str).to_numpy(),
        "participant": rows["pcode"].astype(str).to_numpy(),
        "clip": rows["stimulus"].astype(str).to_numpy(),
        "group": 1,
    })


def too_large(rows: pd.DataFrame) -> str | None:
    """Return why ``rows`` are too many for the models' dense designs, or None."""
    size = len(rows) * (rows["pcode"].nunique() + rows["stimulus"].nunique())
    if size <= MAX_DESIGN:
        return None
    return (f"the mixed model was not fitted: {len(rows)} answers x "
            f"{rows['pcode'].nunique() + rows['stimulus'].nunique()} random effects exceed its "
            f"dense design's limit; the crossed bootstrap stands alone")


def linear(rows: pd.DataFrame, value: str, confidence: float = 0.95) -> dict:
    """Return the crossed linear mixed model of ``value``: ``means`` per source (estimate,
    se, interval), ``differences`` of every pair (Wald tests, Holm) and the variance
    ``components`` (participants, clips, residual)."""
    # Imported here: statsmodels takes seconds to import, and most analyses never fit it.
    import statsmodels.api as sm

    data = _frame(rows, value)
    model = sm.MixedLM.from_formula(
        "y ~ 0 + C(source)", groups="group", re_formula="0", data=data,
        vc_formula={"participant": "0 + C(participant)", "clip": "0 + C(clip)"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # convergence chatter; the result says if it failed
        # statsmodels' default (gradient) optimisers can stop short of the REML optimum
        # where a component's optimum is 0 (seen with 2 clips per source: a clip variance
        # of 1.46 at a REML log-likelihood 4.4 below Powell's 0): fit with both, keep the
        # higher likelihood.
        fits = [model.fit(reml=True)]
        try:
            fits.append(model.fit(reml=True, method="powell"))
        except (ValueError, np.linalg.LinAlgError):
            pass
        fit = max(fits, key=lambda candidate: candidate.llf if np.isfinite(candidate.llf) else -np.inf)
    names = [name[len("C(source)["):-1] for name in fit.fe_params.index]
    estimate = fit.fe_params.to_numpy()
    cov = fit.cov_params().iloc[:len(names), :len(names)].to_numpy()
    z = scipy_stats.norm.ppf(0.5 + confidence / 2)
    se = np.sqrt(np.diag(cov))
    means = pd.DataFrame({"source": names, "estimate": estimate, "se": se,
                          "ci_low": estimate - z * se, "ci_high": estimate + z * se})
    records = []
    for i, j in itertools.combinations(range(len(names)), 2):
        difference = estimate[i] - estimate[j]
        sd = np.sqrt(cov[i, i] + cov[j, j] - 2 * cov[i, j])
        records.append({"a": names[i], "b": names[j], "difference": difference, "se": sd,
                        "ci_low": difference - z * sd, "ci_high": difference + z * sd,
                        "p": float(2 * scipy_stats.norm.sf(abs(difference) / sd))})
    differences = pd.DataFrame(records)
    differences["p_holm"] = holm(differences["p"])
    vc = dict(zip(model.exog_vc.names, np.asarray(fit.vcomp, dtype=float)))
    components = _components({"participants": vc["participant"], "clips": vc["clip"],
                              "residual": float(fit.scale)})
    return {"means": means, "differences": differences, "components": components,
            "converged": bool(fit.converged)}


def logistic(rows: pd.DataFrame, value: str, reference: str, confidence: float = 0.95) -> dict:
    """Return the crossed logistic mixed model of the 0/1 ``value``: each source's
    log-odds difference from ``reference`` (posterior mean and SD, interval, Wald-type
    test, Holm) and the variance ``components`` of the intercepts (logit scale; the
    residual is the logistic distribution's pi^2 / 3)."""
    # Imported here: statsmodels takes seconds to import, and most analyses never fit it.
    from statsmodels.genmod.bayes_mixed_glm import BinomialBayesMixedGLM

    data = _frame(rows, value)
    formula = f"y ~ C(source, Treatment({reference!r}))"
    model = BinomialBayesMixedGLM.from_formula(
        formula, {"participant": "0 + C(participant)", "clip": "0 + C(clip)"}, data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = model.fit_vb()
    z = scipy_stats.norm.ppf(0.5 + confidence / 2)
    records = []
    for name, mean, sd in zip(model.fep_names, fit.fe_mean, fit.fe_sd):
        if "[T." not in name:
            continue
        source = name.split("[T.", 1)[1][:-1]
        records.append({"a": source, "b": reference, "log_odds_difference": mean, "sd": sd,
                        "ci_low": mean - z * sd, "ci_high": mean + z * sd,
                        "p": float(2 * scipy_stats.norm.sf(abs(mean) / sd))})
    differences = pd.DataFrame(records)
    differences["p_holm"] = holm(differences["p"])
    sds = dict(zip(model.vcp_names, np.exp(fit.vcp_mean)))
    components = _components({"participants": sds["participant"] ** 2,
                              "clips": sds["clip"] ** 2, "residual": np.pi ** 2 / 3})
    return {"differences": differences, "components": components}


def _components(variances: dict) -> pd.DataFrame:
    total = sum(variances.values())
    return pd.DataFrame({"component": list(variances), "variance": list(variances.values()),
                         "sd": np.sqrt(list(variances.values())),
                         "share": [v / total for v in variances.values()]})


def linear_tables(rows: pd.DataFrame, value: str, config, unit: str):
    """Return ``(tables, methods, notes, fitted)`` of the linear model for a type's
    analysis (``unit`` names the score, e.g. "rating"); nothing when not asked for."""
    if not getattr(config, "mixed_models", False):
        return [], [], [], None
    reason = too_large(rows)
    if reason:
        return [], [], [reason], None
    fitted = linear(rows, value, config.confidence)
    tables = [
        Table("mixed_model", f"Linear mixed model with crossed random intercepts for participants "
              f"and clips (REML): difference of source means a - b, Wald test (Holm)",
              fitted["differences"]),
        Table("variance_components", f"Variance of a {unit} from participants, clips and the "
              f"residual (the linear mixed model)", fitted["components"]),
    ]
    methods = [f"beside the bootstrap, a linear mixed model of the {unit}s with a mean per source "
               f"and crossed random intercepts for participants and clips was fitted by REML "
               f"(statsmodels MixedLM with variance components); its differences of means are "
               f"Wald tests, Holm-corrected"]
    notes = [] if fitted["converged"] else ["the linear mixed model did not converge: read its "
                                            "table with care"]
    return tables, methods, notes, fitted


def logistic_tables(rows: pd.DataFrame, value: str, reference: str, config):
    """Return ``(tables, methods, notes)`` of the logistic model for fake or real;
    nothing when not asked for."""
    if not getattr(config, "mixed_models", False):
        return [], [], []
    reason = too_large(rows)
    if reason:
        return [], [], [reason]
    fitted = logistic(rows, value, reference, config.confidence)
    tables = [
        Table("mixed_model", "Logistic mixed model with crossed random intercepts for "
              "participants and clips (variational Bayes): log-odds of judged real of each "
              f"source minus {reference}'s, with its test (Holm)", fitted["differences"]),
        Table("variance_components", "Variance of the log-odds from participants, clips and the "
              "residual (the logistic distribution's, pi^2 / 3)", fitted["components"]),
    ]
    methods = [f"beside the bootstrap, a logistic mixed model of judged real with a log-odds "
               f"per source and crossed random intercepts for participants and clips was fitted "
               f"by variational Bayes (statsmodels BinomialBayesMixedGLM); each source is "
               f"compared with {reference} by its posterior mean and SD, Holm-corrected"]
    return tables, methods, []
