"""Graded pairwise preference: two clips, answered on a 7-point scale, or "Both bad".

The answer (column ``choice``) is side-based: ``left_much``, ``left``, ``left_slightly``
(clip A, the left clip, much better / better / slightly better), ``no_preference``,
``right_slightly``, ``right``, ``right_much`` and ``both_bad``. Its grade for clip A runs
from +3 (``left_much``) to -3 (``right_much``).

Reported, every interval and test over participants and clips (:mod:`analysis.crossed`:
participants redrawn with all their judgements, and clips within their source and
condition with all of theirs):

- an ordinal model of the grades (cumulative logit): ``P(grade of A <= k) =
  logistic(c_k - (theta_A - theta_B + beta))`` with a source effect ``theta`` (the
  headline score, logit scale, centred on 0), a left/right shift ``beta`` (> 0: the left
  clip is favoured) and six ordered cut points ``c_k``, symmetric about 0 as the scale is
  (so that ``beta`` is a shift of the answers, not of the cuts);
- Davidson's model of the direction (A better, B better, no preference as a tie), with
  Davidson and Beaver's order effect: ``P(A) : P(B) : P(tie) = g w_A : w_B : nu
  sqrt(w_A w_B)``, ``log w`` per source, ``log g`` the left advantage, ``nu`` the
  propensity to tie;
- the position bias of both models and the raw share of directional answers that favour
  the left clip;
- per pair of sources the directional win rate (tested against 50 % with Holm's
  correction) and the mean grade, and the differences of the ordinal source effects;
- Elo ratings, descriptive only: no model, no interval, averaged over random orders of
  the comparisons because Elo depends on the order it reads them in;
- the share of each source's comparisons answered "Both bad" (those answers carry no
  direction and are left out of both models and of Elo).

Both models are fitted by Fisher scoring on counts per (left source, right source,
answer) cell, batched over bootstrap replicates; a weak normal prior (sd 3) on every
source effect and position term (and on Davidson's log nu) keeps the fit finite when a
source always wins, the left clip always wins or every answer is a tie; the cut points
get half a pseudo-answer of each grade instead.
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd

from analysis import crossed, mixed, simulate, stats
from analysis.counts import ranked_sources, source_counts
from analysis.formatting import estimate_with_interval, p_text, plural
from analysis.pairwise import _matrix_plot, comparisons_answered, sided_pairs
from analysis.registry import (Analysis, AnswerOption, Plot, StudyAnalysis, Table, offered,
                               register_analysis)

SCALE = ("left_much", "left", "left_slightly", "no_preference", "right_slightly", "right",
         "right_much")
BOTH_BAD = "both_bad"
CHOICES = SCALE + (BOTH_BAD,)
GRADE = dict(zip(SCALE, (3, 2, 1, 0, -1, -2, -3)))
N_GRADES = len(SCALE)
# Fewer participants than this: the bootstrap has too few to redraw from.
MIN_PARTICIPANTS = 10
PRIOR_SD = 3.0
# Pseudo-counts per grade on a cell without sources or side: they keep the cut points
# finite and ordered when a grade was never used, and vanish beside real data.
CUT_PSEUDO = 0.5
ELO_K = 16.0
ELO_START = 1500.0
ELO_ORDERS = 20
CHUNK_ELEMENTS = 4_000_000


@register_analysis("pairwise_graded")
class PairwiseGraded(StudyAnalysis):
    """Each trial shows clips A (left) and B (right), answered from "A much better" to
    "B much better", or "Both bad"."""

    answer = "choice"
    mixed_model = "worth"
    agreement_level = "ordinal"
    required = ("position",)
    design = ("each trial showed two clips of one action side by side (A left, B right) and "
              "participants answered on a symmetric 7-point scale from 'A much better' through "
              "'No preference' to 'B much better'")
    answer_options = {"both_bad": AnswerOption(
        ("both_bad",), ", or 'Both bad'", ("both bad",))}

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return simulate.pairs(rng, n_trials, n_sources)

    def simulated_answers(self, raters):
        """The left clip's grade cuts ``q_left - q_right + position_bias + noise * logistic``
        at +-0.5, +-1.5, +-2.5 into the 7-point scale (a cumulative-logit draw);
        ``tie_rate`` of comparisons whose mean quality is below the middle are called both
        bad."""
        rng = raters.rng
        q_left, q_right, careless = simulate.left_right(raters)
        latent = (q_left - q_right + raters.position_bias
                  + raters.noise * rng.logistic(size=len(q_left)))
        # Index into CHOICES: 0 is "left much better" (grade +3), 6 "right much better".
        index = 6 - np.searchsorted(np.array([-2.5, -1.5, -0.5, 0.5, 1.5, 2.5]), latent)
        index = np.where(careless, rng.integers(0, 7, len(q_left)), index)
        bad = ((rng.random(len(q_left)) < raters.tie_rate) & ~careless
               & ((q_left + q_right) / 2 < raters.middle))
        index[bad] = 7
        choices = np.repeat(np.asarray(CHOICES, dtype=object)[index], raters.m)
        return {"choice": pd.Categorical(choices, categories=CHOICES)}

    def answered(self, rows):
        return comparisons_answered(rows, CHOICES, "graded pairwise")

    def judgement_values(self, rows):
        """Return one value per graded comparison: its pair of clips (in a fixed order)
        and the grade of the first clip of that order (-3..3); "Both bad" has no grade."""
        trials = comparisons(rows, sorted(rows["source"].unique()))
        trials = trials.loc[trials["graded"]]
        left, right = trials["left_stimulus"], trials["right_stimulus"]
        if pd.api.types.is_integer_dtype(left) and pd.api.types.is_integer_dtype(right):
            left, right = left.to_numpy(np.int64), right.to_numpy(np.int64)
            unit = np.minimum(left, right) * (1 << 32) + np.maximum(left, right)
        else:
            left, right = left.astype(str).to_numpy(object), right.astype(str).to_numpy(object)
            unit = np.where(left <= right, left + "|" + right, right + "|" + left)
        grade = trials["grade"].to_numpy(np.int64)
        value = np.where(left <= right, grade, -grade)
        return pd.DataFrame({"participant": trials["pcode"].to_numpy(), "unit": unit, "value": value})

    def worth_comparisons(self, rows):
        """Return the graded comparisons as wins of the clip graded better (a grade of 0
        as half a win each way; "Both bad" left out), for the adaptive design's
        Bradley-Terry posterior."""
        names = np.array(sorted(rows["source"].unique()), dtype=object)
        trials = comparisons(rows, list(names))
        trials = trials.loc[trials["graded"]]
        left, right = trials["left"].to_numpy(), trials["right"].to_numpy()
        grade = trials["grade"].to_numpy()
        tie = grade == 0
        winner = np.concatenate([np.where(grade > 0, left, right), right[tie]])
        loser = np.concatenate([np.where(grade > 0, right, left), left[tie]])
        weight = np.concatenate([np.where(tie, 0.5, 1.0), np.full(int(tie.sum()), 0.5)])
        left_clip = trials["left_stimulus"].to_numpy()
        right_clip = trials["right_stimulus"].to_numpy()
        winner_clip = np.concatenate([np.where(grade > 0, left_clip, right_clip), right_clip[tie]])
        loser_clip = np.concatenate([np.where(grade > 0, right_clip, left_clip), left_clip[tie]])
        who = trials["pcode"].to_numpy()
        return pd.DataFrame({"winner": names[winner], "loser": names[loser], "weight": weight,
                             "winner_clip": winner_clip, "loser_clip": loser_clip,
                             "participant": np.concatenate([who, who[tie]])})

    def analyse(self, rows, config):
        names = sorted(rows["source"].unique())
        k = len(names)
        trials = comparisons(rows, names)
        graded = trials.loc[trials["graded"]].reset_index(drop=True)
        graded_rows = rows.loc[rows["trial_key"].isin(graded["trial_key"]).to_numpy()]
        design = crossed.design(graded_rows, unit="trial_key")
        cells = Cells.of(graded.assign(pcode=np.arange(len(graded))), k, len(graded))
        ordinal = fit_crossed(OrdinalModel(cells, k), cells, design, config)
        davidson = fit_crossed(DavidsonModel(cells, k), cells, design, config)
        effects = ordinal.contrast(np.eye(len(ordinal.estimate))[:k])
        shown = crossed.report(effects, names, graded_rows, config)
        worths = crossed.scores(davidson.contrast(np.eye(len(davidson.estimate))[:k]), names,
                                config.confidence)

        sources = source_counts(rows).join(shown.scores[["score", "ci_low", "ci_high"]])
        sources["davidson"] = worths["score"]
        sources["davidson_low"] = worths["ci_low"]
        sources["davidson_high"] = worths["ci_high"]
        sources["elo"] = elo(trials, k, config.seed)
        both_bad, n_shown = both_bad_counts(trials, k)
        with np.errstate(invalid="ignore", divide="ignore"):
            sources["both_bad_share"] = both_bad / n_shown
        sources["both_bad"] = both_bad
        sources = ranked_sources(sources)[[
            "score", "ci_low", "ci_high", "davidson", "davidson_low", "davidson_high", "elo",
            "both_bad_share", "both_bad", "n_participants", "n_judgements"]]

        bias = position_bias(graded, design, ordinal, davidson, k, config)
        pairs, matrix = pair_table(trials, graded, design, names, config)
        cuts = thresholds(ordinal, k, config.confidence)
        n_graded = int(trials["graded"].sum())
        n_both_bad = int((~trials["graded"]).sum())
        n_ties = int((trials["graded"] & (trials["grade"] == 0)).sum())
        n_people = int(trials["pcode"].nunique())
        ci = f"{config.confidence:.0%}"
        tables = [
            Table("sources", f"Source effect of the ordinal (cumulative-logit) model of the grades "
                  f"(logit scale, 0 = average source) with {ci} intervals over "
                  f"participants and clips; Davidson log-worth of the direction (ties = no preference) "
                  f"with its intervals; Elo rating (descriptive, no interval); share of the "
                  f"source's comparisons answered 'Both bad'", sources),
            Table("differences", "Difference of the ordinal model's source effects a - b, t "
                  "test over participants and clips (Holm), and the shares of its variance from "
                  "participants, clips and single answers",
                  shown.differences[crossed.DIFFERENCE_COLUMNS]),
            Table("position_bias", "Left/right position bias: a positive shift, or a share above 0.5, "
                  "means the left clip (A) is favoured (t tests over participants and clips)", bias),
            Table("pairs", f"Per pair of sources: answers, mean grade of a over b, and the win "
                  f"rate of a among directional answers ({ci} intervals over participants and "
                  f"clips, t test against 50 %, Holm)", pairs),
            Table("clips", "Clips per source, and per source and condition", shown.clips),
            Table("thresholds", "Cut points of the ordinal model (grade of A at most the "
                  "category)", cuts),
        ]
        methods = [
            f"the grades (from +3, 'A much better', to -3, 'B much better', for the left clip A) "
            f"were modelled with a cumulative-logit model: P(grade of A <= k) = "
            f"logistic(c_k - (theta_A - theta_B + beta)), with a source effect theta, a left/right "
            f"shift beta and six ordered cut points symmetric about 0 (as the scale is), fitted by maximum likelihood (normal prior "
            f"with SD {PRIOR_SD:g} on each source effect and on the shift) to "
            f"{plural(n_graded, 'graded comparison')}; "
            f"source effects are centred on 0 and compared by their differences, the model "
            f"refitted in every bootstrap resample",
            f"the direction of the answers (A better, B better, or no preference as a tie; "
            f"{plural(n_ties, 'tie')}) was fitted with Davidson's Bradley-Terry model with ties and "
            f"Davidson and Beaver's order effect for the left clip",
            f"position bias: the ordinal model's shift of the left clip was "
            f"{_interval_text(bias, 'ordinal shift beta (logit)')}; Davidson's log order effect "
            f"{_interval_text(bias, 'Davidson log order effect')}; the left clip was favoured in "
            f"{_interval_text(bias, 'share of directional answers favouring the left clip')} "
            f"of directional answers (t test against 0.5: {p_text(_bias_row(bias, 'share of directional answers favouring the left clip')['p'])})",
            "per pair of sources, the win rate among directional answers is tested against 50 % "
            "with Holm's correction",
            shown.method,
            f"Elo ratings (K = {ELO_K:g}, start {ELO_START:g}, averaged over {ELO_ORDERS} random "
            f"orders of the comparisons) are given for comparison only; they are descriptive, "
            f"with no model behind them and no interval",
        ]
        if offered(config, "both_bad", n_both_bad):
            methods.append(
                f"{plural(n_both_bad, 'comparison')} answered 'Both bad' "
                f"{'carries' if n_both_bad == 1 else 'carry'} no direction: "
                f"{'it is' if n_both_bad == 1 else 'they are'} left out of both models and Elo "
                f"and reported as each source's share of its comparisons")
        notes = list(shown.notes)
        if n_people < MIN_PARTICIPANTS:
            notes.append(f"only {n_people} participant(s) were analysed: bootstrap intervals over "
                         f"fewer than {MIN_PARTICIPANTS} participants mean little; collect more "
                         f"before reading them")
        directional = graded.loc[graded["grade"] != 0]
        model_tables, model_methods, model_notes, model = mixed.worth_tables(
            sided_pairs(directional, names, directional["grade"].to_numpy() > 0), names, config,
            sources["davidson"], measure="Davidson log-worth",
            reading="the directional answers, the left clip first; no preference and Both bad "
                    "left out: given a direction, Davidson's model with its order effect is "
                    "Bradley-Terry with a left advantage, with the same worths",
            sided=True, checkpoints=mixed.clip_checkpoints(rows))
        tables += model_tables
        methods += model_methods
        notes += model_notes
        plots = [
            Plot("effects", "Source effect of the ordinal model", _interval_plot(sources)),
            Plot("win_matrix", "Share of directional answers won by each source (row) against "
                 "each other (column)", _matrix_plot(matrix.loc[sources.index, sources.index])),
        ]
        tests = {"position_bias": bias, "n_graded": n_graded, "n_ties": n_ties,
                 "n_both_bad": n_both_bad, "ordinal_converged": ordinal.converged,
                 "davidson_converged": davidson.converged, "differences": shown.differences}
        if model:
            tests["mixed_model"] = model["differences"]
        return Analysis(measure="ordinal source effect (logit scale)", sources=sources,
                        tables=tables, plots=plots, methods=methods, notes=notes, tests=tests)


def comparisons(rows: pd.DataFrame, names) -> pd.DataFrame:
    """Return one row per trial: ``left``/``right`` source codes (index into ``names``),
    ``left_stimulus``/``right_stimulus``, ``choice`` (index into :data:`CHOICES`),
    ``graded`` (not "Both bad"), ``grade`` of the left clip (0 where not graded), ``pcode``
    and ``action``. ``rows`` are sorted by trial and position, two per trial."""
    sources = pd.Categorical(rows["source"], categories=names).codes.astype(np.int64)
    choice = pd.Categorical(rows["choice"], categories=CHOICES).codes[0::2].astype(np.int64)
    grades = np.array([GRADE[c] for c in SCALE] + [0], dtype=np.int64)
    frame = pd.DataFrame({
        "trial_key": rows["trial_key"].to_numpy()[0::2],
        "pcode": rows["pcode"].to_numpy()[0::2].astype(np.int64),
        "left": sources[0::2],
        "right": sources[1::2],
        "left_stimulus": rows["stimulus"].iloc[0::2].to_numpy(),
        "right_stimulus": rows["stimulus"].iloc[1::2].to_numpy(),
        "choice": choice,
        "graded": choice < N_GRADES,
        "grade": grades[choice],
    })
    if "action" in rows.columns:
        frame["action"] = rows["action"].to_numpy()[0::2]
    return frame


class Cells:
    """Graded comparisons as counts: ``pairs`` ``(C, 2)`` the (left, right) sources of each
    cell and ``by_participant`` ``(P, C * 7)`` how often each participant gave each grade
    (category ``grade + 3``) in each cell."""

    def __init__(self, pairs, by_participant):
        self.pairs = pairs
        self.by_participant = by_participant

    @classmethod
    def of(cls, trials, k, n_participants):
        graded = trials.loc[trials["graded"]]
        key = graded["left"].to_numpy() * k + graded["right"].to_numpy()
        present, cell = np.unique(key, return_inverse=True)
        pairs = np.stack([present // k, present % k], axis=1)
        column = cell * N_GRADES + (graded["grade"].to_numpy() + 3)
        counts = np.zeros((n_participants, len(present) * N_GRADES))
        np.add.at(counts, (graded["pcode"].to_numpy(), column), 1.0)
        return cls(pairs, counts)

    def totals(self):
        return self.by_participant.sum(axis=0)


class OrdinalModel:
    """Cumulative logit; parameters: ``theta`` (K), ``beta`` and three log distances ``u``
    that place the cut points symmetrically about the scale's middle: ``t1 = e^u1``,
    ``t2 = t1 + e^u2``, ``t3 = t2 + e^u3``, cuts ``-t3, -t2, -t1, t1, t2, t3``. The scale is
    symmetric, so a shift of all answers towards the left clip is ``beta`` (with free cut
    points it could not be told from a shift of the cuts). One extra cell (no sources, no
    side) holds the cut points' pseudo-counts."""

    def __init__(self, cells: Cells, k: int):
        self.k = k
        n_cells = len(cells.pairs)
        self.n_params = k + 1 + 3
        eta = np.zeros((n_cells + 1, self.n_params))  # d eta / d params
        rows = np.arange(n_cells)
        eta[rows, cells.pairs[:, 0]] += 1.0
        eta[rows, cells.pairs[:, 1]] -= 1.0
        eta[rows, k] = 1.0
        self.deta = eta
        self.n_categories = N_GRADES
        self.prior = np.zeros(self.n_params)
        self.prior[:k + 1] = 1.0 / PRIOR_SD**2  # source effects and the left shift
        self.start = np.concatenate([np.zeros(k + 1), np.log([0.5, 1.0, 1.0])])

    def counts(self, cell_counts):
        """Append the cut points' pseudo-cell to ``(B, C, 7)`` counts."""
        pseudo = np.full(cell_counts.shape[:1] + (1, N_GRADES), CUT_PSEUDO)
        return np.concatenate([cell_counts, pseudo], axis=1)

    def probabilities(self, phi):
        """Return ``p`` ``(B, C, 7)`` and ``dp/dphi`` ``(B, C, 7, n_params)``."""
        k = self.k
        cuts, dcuts = symmetric_cuts(phi, k)
        eta = phi @ self.deta.T  # (B, C)
        cdf = _sigmoid(cuts[:, None, :] - eta[:, :, None])  # (B, C, 6)
        density = cdf * (1 - cdf)
        dcdf = density[..., None] * (dcuts[:, None] - self.deta[None, :, None, :])  # (B, C, 6, P)
        batch_cells = eta.shape
        ones = np.ones(batch_cells + (1,))
        zeros = np.zeros(batch_cells + (1,))
        upper = np.concatenate([cdf, ones], axis=2)
        lower = np.concatenate([zeros, cdf], axis=2)
        p = upper - lower
        zero = np.zeros(batch_cells + (1, self.n_params))
        dp = np.concatenate([dcdf, zero], axis=2) - np.concatenate([zero, dcdf], axis=2)
        return p, dp


def symmetric_cuts(phi, k):
    """Return the six cut points ``(B, 6)`` of parameters ``phi`` ``(B, k + 4)`` and their
    derivatives ``(B, 6, k + 4)``."""
    batch = len(phi)
    steps = np.exp(phi[:, k + 1:k + 4])  # (B, 3)
    t = np.cumsum(steps, axis=1)  # t1, t2, t3
    cuts = np.concatenate([-t[:, ::-1], t], axis=1)
    dt = np.zeros((batch, 3, phi.shape[1]))
    for j in range(3):
        for i in range(j + 1):
            dt[:, j, k + 1 + i] = steps[:, i]
    return cuts, np.concatenate([-dt[:, ::-1], dt], axis=1)


class DavidsonModel:
    """Davidson's ties with an order effect; parameters: log-worth ``theta`` (K), ``log g``
    (the left advantage) and ``log nu`` (ties). Categories: B better, tie, A better."""

    def __init__(self, cells: Cells, k: int):
        self.k = k
        n_cells = len(cells.pairs)
        self.n_params = k + 2
        design = np.zeros((n_cells, 3, self.n_params))  # d s_m / d params
        rows = np.arange(n_cells)
        left, right = cells.pairs[:, 0], cells.pairs[:, 1]
        design[rows, 0, right] = 1.0
        design[rows, 1, left] += 0.5
        design[rows, 1, right] += 0.5
        design[rows, 1, k + 1] = 1.0
        design[rows, 2, left] = 1.0
        design[rows, 2, k] = 1.0
        self.design = design
        self.n_categories = 3
        self.prior = np.full(self.n_params, 1.0 / PRIOR_SD**2)  # every parameter
        self.start = np.zeros(self.n_params)

    def counts(self, cell_counts):
        """Collapse ``(B, C, 7)`` grade counts into B better, tie, A better."""
        return np.stack([cell_counts[..., :3].sum(-1), cell_counts[..., 3],
                         cell_counts[..., 4:].sum(-1)], axis=-1)

    def probabilities(self, phi):
        s = np.einsum("cmp,bp->bcm", self.design, phi)
        s -= s.max(axis=2, keepdims=True)
        p = np.exp(s)
        p /= p.sum(axis=2, keepdims=True)
        mean = np.einsum("bcm,cmp->bcp", p, self.design)
        dp = p[..., None] * (self.design[None] - mean[:, :, None, :])
        return p, dp


def fisher_scoring(model, counts, start, iterations=60, tolerance=1e-8):
    """Return ``(phi (B, n_params), converged)`` maximising the penalised likelihood of
    ``counts`` ``(B, C, M)`` (already in the model's categories) for every row at once."""
    phi = start.copy()
    totals = counts.sum(axis=2)
    converged = False
    for _ in range(iterations):
        p, dp = model.probabilities(phi)
        p = np.maximum(p, 1e-12)
        score = np.einsum("bcm,bcmp->bp", counts / p, dp) - model.prior * phi
        info = np.einsum("bc,bcmp,bcmq->bpq", totals, dp / p[..., None], dp)
        info += np.diag(model.prior)[None] + 1e-9 * np.eye(model.n_params)[None]
        step = np.linalg.solve(info, score[:, :, None])[:, :, 0]
        largest = np.abs(step).max(axis=1, keepdims=True)
        phi += step * np.minimum(1.0, 2.0 / np.maximum(largest, 1e-300))
        if largest.max() < tolerance:
            converged = True
            break
    return phi, converged


def fit_crossed(model, cells: Cells, design, config) -> crossed.Crossed:
    """Return the crossed bootstrap of the model's parameters, source effects centred,
    with the ordinal model's six cut points after them. ``cells`` count each graded
    comparison as its own unit (in the order of ``design``'s units); a replicate weighs
    them by its participants' and clips' draws and refits."""
    n_cells = len(cells.pairs)
    k = model.k
    full = model.counts(cells.totals().reshape(1, n_cells, N_GRADES))
    theta, converged = fisher_scoring(model, full, model.start[None])
    per = max(1, CHUNK_ELEMENTS // ((n_cells + 1) * N_GRADES * model.n_params ** 2))

    def finish(sums):
        out = []
        for first in range(0, len(sums), per):
            counts = np.asarray(sums[first:first + per]).reshape(-1, n_cells, N_GRADES)
            phi, _ = fisher_scoring(model, model.counts(counts), np.tile(theta, (len(counts), 1)))
            phi[:, :k] -= phi[:, :k].mean(axis=1, keepdims=True)
            if isinstance(model, OrdinalModel):
                phi = np.concatenate([phi, symmetric_cuts(phi, k)[0]], axis=1)
            out.append(phi)
        return np.concatenate(out, axis=0)

    result = crossed.bootstrap(design, crossed.Linear(cells.by_participant, finish), config)
    result.converged = converged
    return result


def thresholds(fitted: crossed.Crossed, k, confidence=0.95) -> pd.DataFrame:
    """Return the ordinal model's six cut points (symmetric about 0) with their intervals."""
    summary = fitted.summary(confidence).iloc[k + 4:]
    labels = [f"A's grade <= {g}" for g in range(-3, 3)]
    return pd.DataFrame({"cut": labels, "estimate": summary["estimate"].to_numpy(),
                         "ci_low": summary["ci_low"].to_numpy(),
                         "ci_high": summary["ci_high"].to_numpy()})


def _directional(graded):
    """Return which graded comparisons have a direction (a grade other than 0)."""
    return (graded["grade"] != 0).to_numpy()


def position_bias(graded, design, ordinal, davidson, k, config) -> pd.DataFrame:
    """Return the position bias three ways: the ordinal shift, Davidson's log order effect,
    and the raw share of directional answers that favour the left clip, each with its
    interval and t test over participants and clips."""
    directional = _directional(graded)
    left = int((graded["grade"].to_numpy() > 0).sum())
    n = int(directional.sum())
    groups = np.where(directional, 0, -1)
    share = crossed.bootstrap(design, crossed.ratio((graded["grade"] > 0).to_numpy(float), groups, 1),
                              config)
    raw = share.summary(config.confidence, null=0.5, bounds=(0, 1)).iloc[0]
    shift = ordinal.summary(config.confidence).iloc[k]
    order = davidson.summary(config.confidence).iloc[k]
    n_people = int(graded["pcode"].nunique())
    records = [
        {"measure": "ordinal shift beta (logit)", "estimate": float(shift["estimate"]),
         "ci_low": float(shift["ci_low"]), "ci_high": float(shift["ci_high"]),
         "n": len(graded), "p": float(shift["p"])},
        {"measure": "Davidson log order effect", "estimate": float(order["estimate"]),
         "ci_low": float(order["ci_low"]), "ci_high": float(order["ci_high"]),
         "n": len(graded), "p": float(order["p"])},
        {"measure": "share of directional answers favouring the left clip",
         "estimate": left / n if n else np.nan, "ci_low": float(raw["ci_low"]),
         "ci_high": float(raw["ci_high"]), "n": n, "p": float(raw["p"]) if n else np.nan},
    ]
    frame = pd.DataFrame(records)
    frame["n_participants"] = n_people
    return frame


def pair_table(trials, graded, design, names, config):
    """Return the per-pair table and the ``(K, K)`` matrix of directional win rates; win
    rates have intervals and t tests against 50 % over participants and clips (``design``
    of the ``graded`` comparisons), Holm-corrected."""
    k = len(names)

    def grade_of_first(frame):
        a = np.minimum(frame["left"], frame["right"]).to_numpy()
        b = np.maximum(frame["left"], frame["right"]).to_numpy()
        # The grade of the pair's first source (a), whichever side it was shown on.
        return a, b, np.where(frame["left"].to_numpy() == a, 1, -1) * frame["grade"].to_numpy()

    a, b, grade_a = grade_of_first(trials)
    is_graded = trials["graded"].to_numpy()
    pairs = list(itertools.combinations(range(k), 2))
    ga, gb, g_first = grade_of_first(graded)
    index = {pair: i for i, pair in enumerate(pairs)}
    groups = np.array([index[(i, j)] for i, j in zip(ga, gb)], dtype=np.int64)
    groups = np.where(g_first != 0, groups, -1)
    result = crossed.bootstrap(design, crossed.ratio((g_first > 0).astype(float), groups, len(pairs)),
                               config)
    summary = result.summary(config.confidence, null=0.5, bounds=(0, 1))
    wins = np.zeros((k, k))
    records = []
    for (i, j), row in zip(pairs, summary.itertuples()):
        here = (a == i) & (b == j)
        g = grade_a[here & is_graded]
        won_a, won_b = int((g > 0).sum()), int((g < 0).sum())
        wins[i, j], wins[j, i] = won_a, won_b
        n = won_a + won_b
        records.append({
            "a": names[i], "b": names[j], "n": int(here.sum()), "a_better": won_a,
            "no_preference": int((g == 0).sum()), "b_better": won_b,
            "both_bad": int((here & ~is_graded).sum()),
            "mean_grade_a": float(g.mean()) if len(g) else np.nan,
            "win_rate_a": won_a / n if n else np.nan,
            "ci_low": float(row.ci_low) if n else np.nan,
            "ci_high": float(row.ci_high) if n else np.nan, "p": float(row.p) if n else np.nan,
        })
    table = pd.DataFrame(records)
    if len(table):
        table["p_holm"] = stats.holm(table["p"])
    with np.errstate(invalid="ignore", divide="ignore"):
        matrix = pd.DataFrame(wins / (wins + wins.T), index=names, columns=names)
    return table, matrix


def both_bad_counts(trials, k):
    """Return per source how many of its comparisons were answered "Both bad", and how many
    comparisons showed it."""
    bad = ~trials["graded"].to_numpy()
    left, right = trials["left"].to_numpy(), trials["right"].to_numpy()
    shown = np.bincount(left, minlength=k) + np.bincount(right, minlength=k)
    both = np.bincount(left[bad], minlength=k) + np.bincount(right[bad], minlength=k)
    return both, shown


def elo(trials, k, seed=0) -> np.ndarray:
    """Return each source's Elo rating from the directional answers (a tie scores 0.5),
    averaged over :data:`ELO_ORDERS` random orders of the comparisons. Descriptive only."""
    graded = trials.loc[trials["graded"]]
    left, right = graded["left"].to_numpy(), graded["right"].to_numpy()
    score = 0.5 + 0.5 * np.sign(graded["grade"].to_numpy())
    rng = np.random.default_rng(seed)
    orders = np.stack([rng.permutation(len(graded)) for _ in range(ELO_ORDERS)])  # (R, T)
    rating = np.full((ELO_ORDERS, k), ELO_START)
    rows = np.arange(ELO_ORDERS)
    for step in range(len(graded)):
        t = orders[:, step]
        i, j = left[t], right[t]
        expected = 1.0 / (1.0 + 10 ** ((rating[rows, j] - rating[rows, i]) / 400))
        change = ELO_K * (score[t] - expected)
        rating[rows, i] += change
        rating[rows, j] -= change
    return rating.mean(axis=0)


def _bias_row(bias, measure):
    return bias.set_index("measure").loc[measure]


def _interval_text(bias, measure):
    row = _bias_row(bias, measure)
    return estimate_with_interval(row["estimate"], row["ci_low"], row["ci_high"], 3)


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def _interval_plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "ordinal source effect (logit)", reference=0.0)

    return draw
