"""Mixed models with crossed random intercepts for participants and clips (statsmodels).

Reported beside the crossed bootstrap (:mod:`analysis.crossed`) where a maintained
library fits the model, so that each checks the other:

- scores (ratings 1-5, MUSHRA 0-100): a linear mixed model ``y ~ source`` with random
  intercepts per participant and per clip, crossed (statsmodels ``MixedLM`` with
  variance components over one group, REML); differences of source means are Wald tests
  with t quantiles of the bootstrap's degrees of freedom (:func:`degrees_of_freedom`);
- judged real (fake or real): a logistic mixed model with the same crossed intercepts
  (statsmodels ``BinomialBayesMixedGLM``, variational Bayes; SDs from the Laplace
  covariance, :func:`laplace_covariance`), each source against the real clips on the
  log-odds scale;
- worths (pairs, rankings, best of k): Bradley-Terry as a logistic mixed model on pairs
  with random clip worths and random per-participant worths of each source
  (``BinomialBayesMixedGLM``, Laplace covariance for the fixed effects), each type's
  plug-in giving its pairs (:func:`worth_tables`, :func:`ranked_pairs`).

Training seeds: where a source's clips come from two or more checkpoints (a column
``training_seed``, as the crossed bootstrap reads it), each of those checkpoints gets a
random intercept of its own (a third variance component, ``training seeds``), so that a
source's interval speaks of the method trained again rather than of these checkpoints;
its degrees of freedom count the source's seeds (``seeds - 1``), not its clips. Sources
with one checkpoint, and real clips, get none.

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


def seeded_sources(rows: pd.DataFrame) -> dict:
    """Return ``{source: number of checkpoints}`` of the sources whose clips come from two
    or more training seeds (``training_seed``); empty when none does. Clips of such a
    source without a recorded seed count as one checkpoint more (:func:`checkpoints_of`)."""
    if "training_seed" not in rows.columns or not rows["training_seed"].notna().any():
        return {}
    seed = rows["training_seed"].to_numpy()
    known = pd.notna(seed)
    source = rows["source"].astype(str).to_numpy()
    counts = pd.Series(seed[known]).groupby(source[known]).nunique()
    unknown = set(source[~known])
    return {str(name): int(n) + (name in unknown) for name, n in counts.items() if n >= 2}


def checkpoints_of(rows: pd.DataFrame) -> pd.Series | None:
    """Return the checkpoint of each row's clip (``"source / seed S"``) where its source has
    several training seeds, else None (NaN); None when no source has several. A clip of
    such a source with no recorded seed gets ``"source / seed unknown"``, a checkpoint of
    its own, rather than no seed effect (which would let it anchor the source's estimate)."""
    several = seeded_sources(rows)
    if not several:
        return None
    source = rows["source"].astype(str)
    seed = rows["training_seed"]
    label = source + " / seed " + seed.astype(str).where(seed.notna().to_numpy(), "unknown")
    return label.where(source.isin(list(several)).to_numpy(), None)


def clip_checkpoints(rows: pd.DataFrame) -> dict | None:
    """Return ``{clip id (str): checkpoint}`` of the clips of several-seed sources (for
    :func:`worth`'s pairs), or None when no source has several seeds."""
    labels = checkpoints_of(rows)
    if labels is None:
        return None
    keep = labels.notna().to_numpy()
    return dict(zip(rows["stimulus"].astype(str).to_numpy()[keep], labels.to_numpy()[keep]))


def _variance_formulas(data: pd.DataFrame, rows: pd.DataFrame) -> dict:
    """Return the variance components' formulas of ``data`` (from :func:`_frame`):
    participants, clips and, where a source has several training seeds, ``checkpoint``:
    a 0/1 column per such checkpoint is added to ``data`` (rows of other sources are 0 in
    every column, so they get no seed intercept)."""
    formulas = {"participant": "0 + C(participant)", "clip": "0 + C(clip)"}
    labels = checkpoints_of(rows)
    if labels is not None:
        names = []
        for i, label in enumerate(pd.unique(labels.dropna())):
            names.append(f"checkpoint_{i}")
            data[names[-1]] = (labels.to_numpy() == label).astype(float)
        formulas["checkpoint"] = "0 + " + " + ".join(names)
    return formulas


def _named_variances(by_component: dict) -> dict:
    """Return the fitted variances named as the components table names them."""
    names = {"participant": "participants", "clip": "clips", "checkpoint": "training seeds"}
    return {name: by_component[key] for key, name in names.items() if key in by_component}


def degrees_of_freedom(rows: pd.DataFrame, *sources) -> float:
    """Return the degrees of freedom of a Wald test of ``sources``' means (one: its
    mean; two: their difference): the fewer of the participants' ``P - 1`` and the
    clips', ``m - 1`` summed over the sources' source-and-condition groups (as the
    crossed bootstrap's, Hsu's bound). With 2 clips per source and condition a normal
    quantile treats a clip variance from 2 degrees of freedom as known: the MixedLM's
    Wald z test rejected equal sources in 16.7 % of simulated studies, the same standard
    error with t(2) in 8.3 % (docs/STATISTICS.md). A source with several training seeds
    counts ``seeds - 1`` instead of its clips' (the module's "Training seeds")."""
    by = ["source", "action"] if "action" in rows.columns else ["source"]
    several = seeded_sources(rows)
    wanted = [str(s) for s in sources]
    mine = rows.loc[rows["source"].astype(str).isin([s for s in wanted if s not in several])]
    per_group = mine.groupby(by, observed=True)["stimulus"].nunique()
    # A source trained with several seeds: its seeds are the sampled unit (seeds - 1).
    clip_df = float(np.maximum(per_group.to_numpy() - 1, 0).sum()
                    + sum(several[s] - 1 for s in wanted if s in several))
    participant_df = float(max(rows["pcode"].nunique() - 1, 1))
    return min(participant_df, clip_df) if clip_df > 0 else participant_df


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
    vc_formula = _variance_formulas(data, rows)
    model = sm.MixedLM.from_formula(
        "y ~ 0 + C(source)", groups="group", re_formula="0", data=data, vc_formula=vc_formula)
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
    se = np.sqrt(np.diag(cov))
    df = np.array([degrees_of_freedom(rows, name) for name in names])
    z = scipy_stats.t.ppf(0.5 + confidence / 2, df)
    means = pd.DataFrame({"source": names, "estimate": estimate, "se": se, "df": df,
                          "ci_low": estimate - z * se, "ci_high": estimate + z * se})
    records = []
    for i, j in itertools.combinations(range(len(names)), 2):
        difference = estimate[i] - estimate[j]
        sd = np.sqrt(cov[i, i] + cov[j, j] - 2 * cov[i, j])
        pair_df = degrees_of_freedom(rows, names[i], names[j])
        q = scipy_stats.t.ppf(0.5 + confidence / 2, pair_df)
        records.append({"a": names[i], "b": names[j], "difference": difference, "se": sd,
                        "df": pair_df, "ci_low": difference - q * sd, "ci_high": difference + q * sd,
                        "p": float(2 * scipy_stats.t.sf(abs(difference) / sd, pair_df))})
    differences = pd.DataFrame(records)
    differences["p_holm"] = holm(differences["p"])
    vc = dict(zip(model.exog_vc.names, np.asarray(fit.vcomp, dtype=float)))
    components = _components({**_named_variances(vc), "residual": float(fit.scale)})
    return {"means": means, "differences": differences, "components": components,
            "converged": bool(fit.converged)}


def logistic(rows: pd.DataFrame, value: str, reference: str, confidence: float = 0.95) -> dict:
    """Return the crossed logistic mixed model of the 0/1 ``value``: each source's
    log-odds difference from ``reference`` (posterior mean, its SD from the Laplace
    covariance (:func:`laplace_covariance`), interval, Wald-type test, Holm) and the variance ``components`` of the intercepts (logit scale; the
    residual is the logistic distribution's pi^2 / 3)."""
    # Imported here: statsmodels takes seconds to import, and most analyses never fit it.
    from statsmodels.genmod.bayes_mixed_glm import BinomialBayesMixedGLM

    data = _frame(rows, value)
    formula = f"y ~ C(source, Treatment({reference!r}))"
    model = BinomialBayesMixedGLM.from_formula(formula, _variance_formulas(data, rows), data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = model.fit_vb()
    # The variational posterior is mean-field: its SDs drop the correlation of a source's
    # effect with its own clips' intercepts and come out too narrow; the Laplace
    # covariance keeps it.
    cov = laplace_covariance(model, fit)
    records = []
    for name, mean, sd in zip(model.fep_names, fit.fe_mean, np.sqrt(np.diag(cov))):
        if "[T." not in name:
            continue
        source = name.split("[T.", 1)[1][:-1]
        df = degrees_of_freedom(rows, source, reference)
        q = scipy_stats.t.ppf(0.5 + confidence / 2, df)
        records.append({"a": source, "b": reference, "log_odds_difference": mean, "sd": sd,
                        "df": df, "ci_low": mean - q * sd, "ci_high": mean + q * sd,
                        "p": float(2 * scipy_stats.t.sf(abs(mean) / sd, df))})
    differences = pd.DataFrame(records)
    differences["p_holm"] = holm(differences["p"])
    variances = dict(zip(model.vcp_names, np.exp(fit.vcp_mean) ** 2))
    components = _components({**_named_variances(variances), "residual": np.pi ** 2 / 3})
    return {"differences": differences, "components": components}


def laplace_covariance(model, fit) -> np.ndarray:
    """Return the Laplace covariance of a ``BinomialBayesMixedGLM``'s fixed effects at its
    variational fit: the fixed block of the inverse Hessian of the joint log posterior of
    fixed and random effects (variances held at their fitted values), as the Schur
    complement of the random effects' sparse block. Unlike the mean-field SDs it keeps
    the correlation of the fixed effects with the random ones."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    exog = np.asarray(model.exog, dtype=float)
    exog_vc = sparse.csr_matrix(model.exog_vc)
    sd_vc = np.exp(np.asarray(fit.vcp_mean, dtype=float))[np.asarray(model.ident)]
    eta = exog @ np.asarray(fit.fe_mean, dtype=float) + exog_vc @ np.asarray(fit.vc_mean, dtype=float)
    p = 1.0 / (1.0 + np.exp(-eta))
    w = sparse.diags(p * (1 - p))
    a = exog.T @ (w @ exog) + np.eye(exog.shape[1]) / model.fe_p ** 2
    b = np.asarray((exog_vc.T @ w @ exog))
    c = (exog_vc.T @ w @ exog_vc + sparse.diags(1.0 / sd_vc ** 2)).tocsc()
    return np.linalg.inv(a - b.T @ splu(c).solve(b))


SEED_METHOD = ("where a source's clips came from checkpoints of several training seeds, each "
               "checkpoint had a random effect of its own (a variance component of training "
               "seeds)")


def _seed_method(components: pd.DataFrame, df: bool = True) -> list[str]:
    if "training seeds" not in set(components["component"]):
        return []
    return [SEED_METHOD + (", and that source's degrees of freedom counted its seeds"
                           if df else "")]


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
               f"Wald tests with t quantiles of the bootstrap's degrees of freedom (the fewer of "
               f"the participants' and the compared sources' clips'), Holm-corrected"]
    methods += _seed_method(fitted["components"])
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
               f"compared with {reference} by its posterior mean and its SD from the Laplace "
               f"covariance of the fixed effects (the mean-field variational SDs are too "
               f"narrow), with t quantiles of the bootstrap's degrees of freedom (the fewer of "
               f"the participants' and the compared sources' clips'), Holm-corrected"]
    methods += _seed_method(fitted["components"])
    return tables, methods, []


# --- worth models: Bradley-Terry as a logistic mixed model on pairs -----------------------

# Prior SD of each fixed effect (log-worth against the first source, left advantage): weak
# beside real data, it keeps a source that always wins finite (as the bootstrap's prior).
WORTH_PRIOR_SD = 3.0
# Most pairs a worth model fits (sparse design; variational Bayes over all random effects).
MAX_PAIRS = 400_000


def ranked_pairs(rows: pd.DataFrame, rank: str) -> pd.DataFrame:
    """Return the pairs a trial's ``rank`` column implies (lower = better; rows sorted by
    ``trial_key``, or sorted here): every two clips of a trial with different ranks, the better one won.
    Complete rankings give all their pairs; a best-of-k answer (best 1, the rest 2) gives
    the picked clip against each other clip shown. Columns as :func:`worth` takes them."""
    keys = rows["trial_key"].to_numpy()
    if len(keys) > 1 and not (keys[1:] >= keys[:-1]).all():
        rows = rows.iloc[np.argsort(keys, kind="stable")]
        keys = rows["trial_key"].to_numpy()
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    sizes = np.diff(np.r_[starts, len(keys)])
    ranks = rows[rank].to_numpy(dtype=float)
    first, second = [], []
    for m in np.unique(sizes):
        at = starts[sizes == m]
        for i, j in itertools.combinations(range(int(m)), 2):
            first.append(at + i)
            second.append(at + j)
    if not first:
        return pd.DataFrame(columns=["first", "second", "first_clip", "second_clip",
                                     "participant", "trial", "won"])
    first, second = np.concatenate(first), np.concatenate(second)
    keep = ranks[first] != ranks[second]
    first, second = first[keep], second[keep]
    # The model has no intercept, so a pair's order is arbitrary: put the sources in name
    # order (and alternate within a source), so that the first is not always the winner.
    source = rows["source"].astype(str).to_numpy()
    flip = (source[first] > source[second]) | (
        (source[first] == source[second]) & (np.arange(len(first)) % 2 == 1))
    first, second = np.where(flip, second, first), np.where(flip, first, second)
    return pd.DataFrame({
        "first": rows["source"].to_numpy()[first], "second": rows["source"].to_numpy()[second],
        "first_clip": rows["stimulus"].to_numpy()[first],
        "second_clip": rows["stimulus"].to_numpy()[second],
        "participant": rows["pcode"].to_numpy()[first], "trial": keys[first],
        "won": (ranks[first] < ranks[second]).astype(float)})


def worth(pairs: pd.DataFrame, names, *, sided: bool = False, clustered: bool = False,
          confidence: float = 0.95, prior_sd: float = WORTH_PRIOR_SD,
          checkpoints: dict | None = None) -> dict:
    """Return the Bradley-Terry logistic mixed model of ``pairs``.

    ``pairs`` has one row per comparison: sources ``first``/``second``, clips
    ``first_clip``/``second_clip``, ``participant``, ``trial`` and ``won`` (1 when the
    first was preferred). The model: ``logit P(first won) = theta_first - theta_second
    (+ beta, the left advantage, when ``sided``: the first clip was the left one)
    + u_first_clip - u_second_clip + v_participant,first - v_participant,second``, with
    random clip worths ``u`` and random per-participant worths of each source ``v``
    (two variance components, crossed), fitted by variational Bayes (statsmodels
    ``BinomialBayesMixedGLM``). Intervals and tests use the Laplace covariance of the
    fixed effects at the fitted random effects and variances (the fixed block of the
    inverse Hessian of the joint log posterior), which keeps the correlation of a source's
    worth with its clips' that the variational posterior drops.

    ``checkpoints`` (``{clip id: checkpoint}``, :func:`clip_checkpoints`): clips of
    sources trained with several seeds; each checkpoint gets a random worth of its own, a
    third variance component (the module's "Training seeds").

    ``clustered``: a trial gave several pairs (rankings, best of k), which the model
    treats as independent; each variance is then multiplied by the ratio of the
    trial-clustered (sandwich) to the naive variance of the same contrast in the
    fixed-effects logit (statsmodels ``GLM``), as for a composite likelihood.

    Returns ``scores`` (log-worth per source centred on 0: estimate, sd, interval),
    ``differences`` (a - b, Wald tests, Holm), ``components``, ``position`` (when
    ``sided``), ``widening`` (per score, 1 when not clustered) and ``n_pairs``.
    """
    from scipy import sparse
    from statsmodels.genmod.bayes_mixed_glm import BinomialBayesMixedGLM

    names = list(names)
    k, n = len(names), len(pairs)
    first = pd.Categorical(pairs["first"], categories=names).codes.astype(np.int64)
    second = pd.Categorical(pairs["second"], categories=names).codes.astype(np.int64)
    y = pairs["won"].to_numpy(dtype=float)
    at = np.arange(n)
    difference = np.zeros((n, k))
    np.add.at(difference, (at, first), 1.0)
    np.add.at(difference, (at, second), -1.0)
    exog = difference[:, 1:]  # the first source is the reference (log-worth 0)
    fixed_names = [f"theta[{name}]" for name in names[1:]]
    if sided:
        exog = np.column_stack([np.ones(n), exog])
        fixed_names = ["left"] + fixed_names
    clip_codes, _ = pd.factorize(np.concatenate([pairs["first_clip"].astype(str).to_numpy(),
                                                 pairs["second_clip"].astype(str).to_numpy()]))
    n_clips = int(clip_codes.max()) + 1
    person = pd.factorize(pairs["participant"].astype(str))[0]
    ones = np.ones(n)
    clips = sparse.csr_matrix((np.r_[ones, -ones], (np.r_[at, at], clip_codes)),
                              shape=(n, n_clips))
    people = sparse.csr_matrix((np.r_[ones, -ones], (np.r_[at, at], np.r_[person * k + first,
                                                                         person * k + second])),
                               shape=(n, (int(person.max()) + 1) * k))
    people = people[:, np.flatnonzero(people.getnnz(axis=0))]
    clips.sum_duplicates()
    blocks, ident, vcp_names = [people, clips], [np.zeros(people.shape[1], dtype=int),
                                                 np.ones(n_clips, dtype=int)], ["participant", "clip"]
    seeded = _checkpoint_block(pairs, checkpoints, at)
    if seeded is not None:
        blocks.append(seeded)
        ident.append(np.full(seeded.shape[1], 2, dtype=int))
        vcp_names.append("checkpoint")
    exog_vc = sparse.hstack(blocks).tocsr()
    model = BinomialBayesMixedGLM(y, exog, exog_vc, np.concatenate(ident), vcp_p=1.0,
                                  fe_p=prior_sd, fep_names=fixed_names, vcp_names=vcp_names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = model.fit_vb()
    fixed = np.asarray(fit.fe_mean, dtype=float)
    sd_vc = np.exp(np.asarray(fit.vcp_mean, dtype=float))

    cov_fixed = laplace_covariance(model, fit)

    offset = 1 if sided else 0
    theta = np.r_[0.0, fixed[offset:]]
    cov = np.zeros((k, k))
    cov[1:, 1:] = cov_fixed[offset:, offset:]
    centre = np.eye(k) - 1.0 / k
    widening = np.ones(k)
    pair_widening = {}
    notes = []
    if clustered:
        ratio = _cluster_ratio(y, exog, pairs["trial"].to_numpy(), offset, k)
        if ratio is None:
            notes.append("the fixed-effects logit of the pairs did not fit (a source always "
                          "won or lost?): the mixed model's intervals were not widened for "
                          "the pairs' dependence within trials; read them as too narrow")
        else:
            widening = np.array([ratio(row) for row in centre])
            pair_widening = {(i, j): ratio(np.eye(k)[i] - np.eye(k)[j])
                             for i, j in itertools.combinations(range(k), 2)}
    z = scipy_stats.norm.ppf(0.5 + confidence / 2)
    estimate = centre @ theta
    se = np.sqrt(np.diag(centre @ cov @ centre.T) * widening)
    scores = pd.DataFrame({"source": names, "estimate": estimate, "sd": se,
                           "ci_low": estimate - z * se, "ci_high": estimate + z * se})
    records = []
    for i, j in itertools.combinations(range(k), 2):
        diff = theta[i] - theta[j]
        sd = np.sqrt((cov[i, i] + cov[j, j] - 2 * cov[i, j]) * pair_widening.get((i, j), 1.0))
        records.append({"a": names[i], "b": names[j], "difference": diff, "sd": sd,
                        "ci_low": diff - z * sd, "ci_high": diff + z * sd,
                        "p": float(2 * scipy_stats.norm.sf(abs(diff) / sd)) if sd > 0 else np.nan})
    differences = pd.DataFrame(records, columns=["a", "b", "difference", "sd", "ci_low",
                                                 "ci_high", "p"])
    differences["p_holm"] = holm(differences["p"]) if len(differences) else []
    variances = dict(zip(vcp_names, sd_vc ** 2))
    components = _components({**_named_variances(variances), "residual": np.pi ** 2 / 3})
    result = {"scores": scores, "differences": differences, "components": components,
              "widening": widening, "n_pairs": n, "notes": notes}
    if sided:
        sd = float(np.sqrt(cov_fixed[0, 0]))
        result["position"] = {"estimate": float(fixed[0]), "sd": sd,
                              "ci_low": float(fixed[0] - z * sd), "ci_high": float(fixed[0] + z * sd),
                              "p": float(2 * scipy_stats.norm.sf(abs(fixed[0]) / sd))}
    return result


def _checkpoint_block(pairs: pd.DataFrame, checkpoints: dict | None, at: np.ndarray):
    """Return the pairs' design of the checkpoints' random worths (+1 the first clip's
    checkpoint, -1 the second's; 0 for clips of one-checkpoint sources), or None."""
    if not checkpoints:
        return None
    from scipy import sparse

    first = pairs["first_clip"].astype(str).map(checkpoints)
    second = pairs["second_clip"].astype(str).map(checkpoints)
    labels = pd.unique(pd.concat([first, second]).dropna())
    if len(labels) == 0:
        return None
    code = {label: i for i, label in enumerate(labels)}
    rows, columns, values = [], [], []
    for side, sign in ((first, 1.0), (second, -1.0)):
        known = side.notna().to_numpy()
        rows.append(at[known])
        columns.append(side[known].map(code).to_numpy(dtype=np.int64))
        values.append(np.full(int(known.sum()), sign))
    block = sparse.csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(columns))),
                              shape=(len(pairs), len(labels)))
    block.sum_duplicates()
    block.eliminate_zeros()
    return block


def _cluster_ratio(y, exog, groups, offset, k):
    """Return a function of a contrast ``(k,)`` of the log-worths giving the ratio of its
    trial-clustered to its naive variance in the fixed-effects logit, or None if the
    logit does not fit."""
    import statsmodels.api as sm

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = sm.GLM(y, exog, family=sm.families.Binomial())
            naive = model.fit()
            robust = model.fit(cov_type="cluster", cov_kwds={"groups": pd.factorize(groups)[0]})
    except Exception:  # perfect separation and the like: reported, not raised
        return None
    v_naive = np.asarray(naive.cov_params())[offset:, offset:]
    v_robust = np.asarray(robust.cov_params())[offset:, offset:]
    if not (np.all(np.isfinite(v_naive)) and np.all(np.isfinite(v_robust))):
        return None

    def ratio(contrast):
        c = np.asarray(contrast, dtype=float)[1:]
        return float((c @ v_robust @ c) / (c @ v_naive @ c))

    return ratio


def worth_tables(pairs: pd.DataFrame, names, config, bootstrap_scores: pd.Series, *,
                 measure: str, reading: str, sided: bool = False, clustered: bool = False,
                 bootstrap_label: str = "bootstrap", checkpoints: dict | None = None):
    """Return ``(tables, methods, notes, fitted)`` of the Bradley-Terry mixed model for a
    worth type's analysis: its worths beside ``bootstrap_scores`` (the crossed
    bootstrap's, by source), its differences and variance components; nothing when not
    asked for. ``measure`` names the bootstrap's model ("Plackett-Luce worth"),
    ``reading`` says which pairs the answers gave (for the methods paragraph)."""
    if not getattr(config, "mixed_models", False):
        return [], [], [], None
    if len(pairs) > MAX_PAIRS:
        return [], [], [f"the mixed model was not fitted: {len(pairs)} pairs exceed its limit of "
                        f"{MAX_PAIRS}; the crossed bootstrap stands alone"], None
    if len(pairs) == 0 or len(names) < 2:
        return [], [], ["the mixed model was not fitted: no pairs of two sources to fit"], None
    fitted = worth(pairs, names, sided=sided, clustered=clustered, confidence=config.confidence,
                   checkpoints=checkpoints)
    scores = fitted["scores"].set_index("source")
    scores[bootstrap_label] = bootstrap_scores.reindex(scores.index)
    if clustered:
        scores["widening"] = fitted["widening"]
    ci = f"{config.confidence:.0%}"
    tables = [
        Table("mixed_model_worth", f"Bradley-Terry log-worth (0 = average source) of a logistic "
              f"mixed model with random clip worths and random per-participant worths (variational "
              f"Bayes; {ci} intervals from its Laplace covariance), beside the crossed bootstrap's "
              f"{measure} ({bootstrap_label})", scores.reset_index()),
        Table("mixed_model", "Difference of the mixed model's log-worths a - b, Wald test (Holm)",
              fitted["differences"]),
        Table("variance_components", "Variance of the log-odds from participants' own worths of "
              "a source, clips' worths and the residual (the logistic distribution's, pi^2 / 3)",
              fitted["components"]),
    ]
    methods = [
        f"beside the bootstrap, a Bradley-Terry model was fitted as a logistic mixed model to "
        f"{fitted['n_pairs']} pairs ({reading}): logit P(first preferred) = theta_first - "
        f"theta_second{' + a left advantage' if sided else ''} plus the difference of the two "
        f"clips' random worths and of the participant's random worths of the two sources "
        f"(crossed variance components), by variational Bayes (statsmodels "
        f"BinomialBayesMixedGLM, normal prior SD {WORTH_PRIOR_SD:g} on fixed effects); its "
        f"intervals and Wald tests (Holm) use the Laplace covariance of the fixed effects "
        f"and normal quantiles (with few clips per source they hold less often than stated: "
        f"read the bootstrap's t intervals)"
        + ("; as a trial's pairs are not independent, each variance was multiplied by the ratio "
           "of the trial-clustered (sandwich) to the naive variance of the same contrast in the "
           "fixed-effects logit" if clustered else "")]
    methods += _seed_method(fitted["components"], df=False)
    if sided:
        position = fitted["position"]
        methods.append(f"the mixed model's left advantage (log-odds) was "
                       f"{position['estimate']:.3f} [{position['ci_low']:.3f}, "
                       f"{position['ci_high']:.3f}]")
    return tables, methods, list(fitted["notes"]), fitted
