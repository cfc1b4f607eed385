"""Inference with participants and clips both random: the crossed bootstrap.

A study shows a few clips of each source and condition, and a reader wants a verdict
about the source (the method), not about those clips. Participants and clips are then
two crossed random samples, and an interval that resamples participants only holds the
clips fixed: with few clips whose quality varies it excludes zero between two sources of
equal quality most of the time.

Any statistic of a response table is computed from unit weights (a unit is a row, or a
trial with all its clips). Three one-way bootstraps give three variances of it:

- ``V_p``: participants drawn with replacement (a unit's weight is how often its
  participant was drawn);
- ``V_c``: clips drawn with replacement within their stratum (source and condition), a
  unit weighted by the product of its clips' counts;
- ``V_obs``: units drawn with replacement within their cell (the units that showed the
  same clips): the noise of single answers, which ``V_p`` and ``V_c`` both contain.

The interval is ``estimate -/+ t(df) sqrt(V)`` with
``V = V_p + max(V_c m / (m - 1) - k V_obs, 0)`` (``m`` clips per stratum: resampling
``m`` clips shrinks their variance by ``(m - 1) / m``; a unit's ``k`` clips each carry
its answers' noise into ``V_c``) and ``df`` the fewer of ``P - 1`` participant and the
clip degrees of freedom of the value: ``m_s - 1`` summed over the strata whose clips move
it (a difference of two sources: their clips only, ``2 (m - 1)``; found from each clip's
influence, :func:`clip_influence`), also when the clips' part comes out 0. A percentile
interval from drawing both at once under-covers with 2 clips per stratum (see
``docs/STATISTICS.md``); the t interval reaches its level there. A test of a difference
is the t test of the same standard error; families of them are Holm-corrected.

The variance of an estimate is split into what participants, clips and single answers
(residual) contribute; when the clips' part is the larger, the report says that the
difference may be about these clips rather than the sources.

Training seeds: a method source whose clips come from several checkpoints (a column
``training_seed`` with two or more seeds for the source) has its clips nested in those
checkpoints, and the checkpoints are a sample of the method's trainings. For such a source
the clips' bootstrap redraws whole training seeds (with all their clips, every action)
within the source, instead of clips within source and condition: the variance of a seed's
mean holds its clips' variance too, so the interval speaks of the method trained again,
not of these checkpoints. Its ``m`` is then the seeds per source and its clip degrees of
freedom ``seeds - 1``; sources with one checkpoint (and real clips) keep their clips as
the resampled unit. :attr:`Design.units` maps each clip to its resampled unit.
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import sparse
from scipy import stats as scipy_stats

from analysis import worth
from analysis.stats import holm

# Largest (replicates x units) weight array held at once.
CHUNK_ELEMENTS = 4_000_000
# Above this share of an estimate's variance from clips, the report warns in words.
CLIP_DOMINANCE = 0.5


@dataclass
class Design:
    """Who and what each unit of a table involves.

    ``participants`` ``(N,)`` codes ``0..P-1``; ``clips`` ``(N, k)`` clip codes
    ``0..C-1`` (``-1`` pads units with fewer clips); ``strata`` ``(C,)`` the stratum
    (source and condition) of each clip; ``cells`` ``(N,)`` the code of the set of
    clips a unit showed.
    """

    participants: np.ndarray
    clips: np.ndarray
    strata: np.ndarray
    cells: np.ndarray
    # The resampled unit of each clip (C,) and the stratum of each unit (U,): by default
    # the clip itself in its stratum; a source's training seed (all its clips) when the
    # source has several (see the module).
    units: np.ndarray | None = None
    unit_strata: np.ndarray | None = None
    seeded: np.ndarray | None = None  # (U,) whether a unit is a training seed

    def __post_init__(self):
        if self.units is None:
            self.units = np.arange(len(self.strata), dtype=np.int64)
            self.unit_strata = np.asarray(self.strata, dtype=np.int64)

    @property
    def n_resampled(self) -> int:
        """Return the number of resampled units (clips, or training seeds for the sources
        trained with several)."""
        return len(self.unit_strata)

    @property
    def n_seeds(self) -> int:
        """Return how many training seeds are resampled whole (0: clips only)."""
        return 0 if self.seeded is None else int(np.sum(self.seeded))

    @property
    def units_per_stratum(self) -> np.ndarray:
        """Return the number of resampled units in each unit stratum that has any."""
        sizes = np.bincount(self.unit_strata)
        return sizes[sizes > 0]

    @property
    def n_units(self) -> int:
        return len(self.participants)

    @property
    def n_participants(self) -> int:
        return int(self.participants.max()) + 1 if len(self.participants) else 0

    @property
    def n_clips(self) -> int:
        return len(self.strata)

    @property
    def n_strata(self) -> int:
        return len(np.unique(self.strata))

    @property
    def clips_per_stratum(self) -> np.ndarray:
        """Return the number of clips in each stratum that has any."""
        sizes = np.bincount(self.strata)
        return sizes[sizes > 0]

    @property
    def clips_per_unit(self) -> float:
        """Return the mean number of clips a unit involves."""
        return float(np.mean(np.sum(self.clips >= 0, axis=1))) if self.n_units else 1.0

    @property
    def m(self) -> float:
        """Return the harmonic mean of the resampled units (clips, or training seeds) per
        stratum over strata with two or more (``nan`` when none has two: the clips'
        variance cannot be estimated)."""
        sizes = self.units_per_stratum
        sizes = sizes[sizes >= 2]
        return float(len(sizes) / np.sum(1.0 / sizes)) if len(sizes) else float("nan")


def design(rows: pd.DataFrame, unit: str | None = None, clip: str = "stimulus",
           strata=("source", "action"), participant: str = "pcode",
           seed: str = "training_seed") -> Design:
    """Return the :class:`Design` of ``rows``.

    With ``unit`` (e.g. ``"trial_key"``) the units are the groups of rows with one value
    of it, in order of first appearance (pairwise and ranking trials: a unit's weight
    involves all its clips); without, every row is a unit. A clip is one value of
    ``clip`` (a source's motion, whatever its renderings and repeats); its stratum is
    its value of the ``strata`` columns that ``rows`` has. A source (``strata[0]``) whose
    clips carry two or more values of ``seed`` has its training seeds resampled instead
    of its clips (the module's "Training seeds").
    """
    clip_codes, _ = pd.factorize(rows[clip])
    columns = [c for c in strata if c in rows.columns]
    stratum_of_row = (rows.groupby(columns, observed=True, sort=False, dropna=False).ngroup()
                      .to_numpy() if columns else np.zeros(len(rows), dtype=np.int64))
    n_clips = int(clip_codes.max()) + 1 if len(clip_codes) else 0
    strata_codes = np.zeros(n_clips, dtype=np.int64)
    strata_codes[clip_codes] = stratum_of_row
    people = rows[participant].to_numpy()
    if unit is None:
        unit_clips = clip_codes[:, None].astype(np.int64)
        unit_people = people
    else:
        unit_codes, _ = pd.factorize(rows[unit])
        n_units = int(unit_codes.max()) + 1 if len(unit_codes) else 0
        slot = pd.Series(unit_codes).groupby(unit_codes).cumcount().to_numpy()
        unit_clips = np.full((n_units, int(slot.max()) + 1 if len(slot) else 1), -1, dtype=np.int64)
        unit_clips[unit_codes, slot] = clip_codes
        unit_people = np.zeros(n_units, dtype=people.dtype)
        unit_people[unit_codes] = people
    unit_people = pd.factorize(unit_people)[0]
    ordered = np.sort(unit_clips, axis=1)
    cells = np.unique(ordered, axis=0, return_inverse=True)[1].ravel()
    units, unit_strata, seeded = _seed_units(rows, clip_codes, strata_codes, n_clips,
                                             strata[0] if strata else None, seed)
    return Design(unit_people.astype(np.int64), unit_clips, strata_codes, cells.astype(np.int64),
                  units, unit_strata, seeded)


def _seed_units(rows, clip_codes, strata_codes, n_clips: int, source: str | None, seed: str):
    """Return the resampled unit of each clip, each unit's stratum and whether it is a
    seed: a clip in its own stratum, or, for a source with two or more training seeds,
    its seed in the source (``None`` thrice when no source has several)."""
    if (source is None or seed not in rows.columns or source not in rows.columns
            or not rows[seed].notna().any()):
        return None, None, None
    per_clip = pd.DataFrame({"clip": clip_codes, "source": rows[source].to_numpy(),
                             "seed": rows[seed].to_numpy()}).drop_duplicates("clip")
    per_clip = per_clip.set_index("clip").reindex(range(n_clips))
    seeds_of = per_clip.groupby("source", observed=True, dropna=False)["seed"].nunique()
    several = per_clip["source"].map(seeds_of).fillna(0).to_numpy() >= 2
    several &= per_clip["seed"].notna().to_numpy()
    if not several.any():
        return None, None, None
    # Units: seeds of such sources (keyed by source and seed), clips of the rest.
    key = np.where(several, "seed\x00" + per_clip["source"].astype(str) + "\x00"
                   + per_clip["seed"].astype(str), "clip\x00" + pd.Series(range(n_clips)).astype(str))
    units, _ = pd.factorize(pd.Series(key))
    stratum_key = np.where(several, "source\x00" + per_clip["source"].astype(str),
                           "stratum\x00" + pd.Series(strata_codes).astype(str))
    stratum_codes = pd.factorize(pd.Series(stratum_key))[0]
    unit_strata = np.zeros(int(units.max()) + 1, dtype=np.int64)
    unit_strata[units] = stratum_codes
    seeded = np.zeros(len(unit_strata), dtype=bool)
    seeded[units] = several
    return units.astype(np.int64), unit_strata, seeded


def draws_within(groups: np.ndarray, repeats: int, rng) -> np.ndarray:
    """Return ``(repeats, n)`` counts: each group of ``groups`` ``(n,)`` redrawn with
    replacement to its own size (multinomial counts within groups)."""
    groups = np.asarray(groups, dtype=np.int64)
    n = len(groups)
    order = np.argsort(groups, kind="stable")
    sizes = np.bincount(groups)
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    sorted_groups = groups[order]
    first, size = starts[sorted_groups], sizes[sorted_groups]
    # One draw per member and replicate, all at once: replicate r's draws land in r * n + unit.
    picked = first + (rng.random((repeats, n), dtype=np.float32) * size).astype(np.int64)
    np.minimum(picked, first + size - 1, out=picked)  # float32 rounding may reach the size
    flat = (np.arange(repeats, dtype=np.int64)[:, None] * n + order[picked]).ravel()
    # Counts are small whole numbers: float32 holds them exactly, at half the traffic.
    return np.bincount(flat, minlength=repeats * n).reshape(repeats, n).astype(np.float32)


def unit_weights(design: Design, scheme: str, repeats: int, rng) -> np.ndarray:
    """Return ``(repeats, N)`` unit weights of one resampling ``scheme``: ``participants``,
    ``clips``, ``observations`` or ``both`` (participants and clips at once)."""
    if scheme == "observations":
        return draws_within(design.cells, repeats, rng)
    weights = None
    if scheme in ("participants", "both"):
        drawn = draws_within(np.zeros(design.n_participants, dtype=np.int64), repeats, rng)
        weights = drawn[:, design.participants]
    if scheme in ("clips", "both"):
        drawn = draws_within(design.unit_strata, repeats, rng)[:, design.units]
        drawn = np.concatenate([drawn, np.ones((repeats, 1), dtype=np.float32)], axis=1)  # -1 pads
        for column in design.clips.T:
            weights = drawn[:, column] if weights is None else weights * drawn[:, column]
    return np.ones((repeats, design.n_units), dtype=np.float32) if weights is None else weights


class Linear:
    """A statistic that sees unit weights only through their sums ``weights @ matrix``.

    ``matrix`` sparse ``(N, F)`` (a unit's counts or sums of what the statistic needs);
    ``finish`` maps ``(B, F)`` weighted sums to ``(B, K)`` values. Calling it with
    ``(B, N)`` weights gives the statistic; :func:`bootstrap` instead draws the sums from
    per-participant, per-set-of-clips and per-distinct-answer sufficient statistics, so
    no ``(B, N)`` weight array is built.
    """

    def __init__(self, matrix, finish):
        self.matrix = sparse.csr_matrix(matrix, dtype=float)
        self.finish = finish

    def __call__(self, weights):
        return self.finish(np.asarray(weights @ self.matrix, dtype=float))


def _indicator(codes, n_groups: int) -> sparse.csr_matrix:
    """Return the sparse ``(n_groups, N)`` indicator of ``codes`` ``(N,)``."""
    codes = np.asarray(codes, dtype=np.int64)
    return sparse.csr_matrix((np.ones(len(codes)), (codes, np.arange(len(codes)))),
                             shape=(n_groups, len(codes)))


def _row_keys(matrix: sparse.csr_matrix) -> np.ndarray:
    """Return a code per row of ``matrix`` naming equal rows alike (two fixed random
    projections of each row, rounded: distinct rows of counts and sums collide with
    negligible probability)."""
    probe = np.random.default_rng(12345).random((matrix.shape[1], 2)) + 0.5
    projected = np.round(np.asarray(matrix @ probe), 9)
    return _joint_codes(pd.factorize(projected[:, 0])[0], pd.factorize(projected[:, 1])[0])


def _joint_codes(first, second) -> np.ndarray:
    """Return codes ``0..`` of the pairs of non-negative integer codes ``first``, ``second``."""
    first, second = np.asarray(first, dtype=np.int64), np.asarray(second, dtype=np.int64)
    base = int(second.max()) + 1 if len(second) else 1
    return pd.factorize(first * base + second)[0]


def _aggregated_replicates(design, statistic: Linear, scheme, repeats, rng):
    """Return ``(repeats, K)`` replicates of a :class:`Linear` statistic, each drawn as
    sums over groups whose units always share a weight: participants (participants'
    scheme), sets of clips (clips' scheme, a set's weight the product of its clips'
    counts), and distinct answers within a set of clips (single answers' scheme: a
    multinomial draw of how many of the set's units give each distinct answer)."""
    matrix = statistic.matrix
    width = matrix.shape[1]
    if scheme == "participants":
        grouped = _indicator(design.participants, design.n_participants) @ matrix

        def sums(size):
            drawn = draws_within(np.zeros(design.n_participants, dtype=np.int64), size, rng)
            return np.asarray(grouped.T @ drawn.T).T
        groups = design.n_participants
    elif scheme == "clips":
        cells, first = np.unique(design.cells, return_index=True)
        members = design.clips[first]
        grouped = _indicator(np.searchsorted(cells, design.cells), len(cells)) @ matrix

        def sums(size):
            drawn = draws_within(design.unit_strata, size, rng)[:, design.units]
            # Clips by replicates, so that a set's weights are contiguous rows to multiply.
            drawn = np.concatenate([drawn.T, np.ones((1, size), dtype=np.float32)], axis=0)
            weights = drawn[members[:, 0]]
            for column in members[:, 1:].T:
                weights *= drawn[column]
            return np.asarray(grouped.T @ weights).T
        groups = len(cells)
    else:
        # Units of one set of clips with the same row give the same sums: only how many of
        # the set's units give each distinct row is random (a multinomial of the set's size).
        kinds = _joint_codes(design.cells, _row_keys(matrix))
        n_kinds = int(kinds.max()) + 1 if len(kinds) else 0
        size_of_kind = np.bincount(kinds, minlength=n_kinds).astype(float)
        cell_of_kind = np.zeros(n_kinds, dtype=np.int64)
        cell_of_kind[kinds] = design.cells
        row_of_kind = sparse.diags(1.0 / np.maximum(size_of_kind, 1)) @ (_indicator(kinds, n_kinds) @ matrix)
        kinds_in_cell = np.bincount(cell_of_kind)
        varied = kinds_in_cell[cell_of_kind] > 1
        fixed = np.asarray(size_of_kind[~varied] @ row_of_kind[np.flatnonzero(~varied)]).ravel()
        order = np.flatnonzero(varied)
        order = order[np.argsort(cell_of_kind[order], kind="stable")]
        cells, start, per_cell = np.unique(cell_of_kind[order], return_index=True, return_counts=True)
        slot = np.arange(len(order)) - np.repeat(start, per_cell)
        widest = int(per_cell.max()) if len(per_cell) else 1
        probabilities = np.zeros((len(cells), widest))
        probabilities[np.repeat(np.arange(len(cells)), per_cell), slot] = size_of_kind[order]
        totals = probabilities.sum(axis=1)
        probabilities /= np.maximum(totals, 1)[:, None]
        if not len(cells):  # every set of clips gave one answer: nothing varies, one fit
            return np.tile(np.asarray(statistic.finish(fixed[None]), dtype=float), (repeats, 1))
        varied_rows = row_of_kind[order]
        flat = np.repeat(np.arange(len(cells)), per_cell) * widest + slot

        def sums(size):
            drawn = rng.multinomial(totals.astype(np.int64), probabilities, size=(size, len(cells)))
            drawn = drawn.reshape(size, -1)[:, flat].astype(float)
            return fixed + np.asarray(varied_rows.T @ drawn.T).T
        groups = len(cells) * widest
    per_chunk = max(1, CHUNK_ELEMENTS // max(groups, width, 1))
    parts = []
    for first_replicate in range(0, repeats, per_chunk):
        size = min(per_chunk, repeats - first_replicate)
        parts.append(np.asarray(statistic.finish(sums(size)), dtype=float))
    return np.concatenate(parts, axis=0)


def _replicates(design, statistic, scheme, repeats, rng):
    if isinstance(statistic, Linear) and scheme != "both":
        return _aggregated_replicates(design, statistic, scheme, repeats, rng)
    per_chunk = max(1, CHUNK_ELEMENTS // max(design.n_units, 1))
    parts = []
    for first in range(0, repeats, per_chunk):
        size = min(per_chunk, repeats - first)
        parts.append(np.asarray(statistic(unit_weights(design, scheme, size, rng)), dtype=float))
    return np.concatenate(parts, axis=0)


def clip_influence(design: Design, statistic, estimate: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """Return ``(C, K)``: how the statistic moves when one clip's weight grows by
    ``step`` (a unit's weight by ``(1 + step)`` per time it shows the clip), per unit of
    ``step`` (the infinitesimal jackknife's influence of each clip). Only whether it moves
    is used: a value that no clip of a stratum moves gets no clip degrees of freedom from
    that stratum."""
    n_clips = design.n_clips
    shown = design.clips >= 0
    counts = sparse.csr_matrix((np.ones(int(shown.sum())), (design.clips[shown],
                                np.nonzero(shown)[0])), shape=(n_clips, design.n_units))
    per_chunk = max(1, CHUNK_ELEMENTS // max(design.n_units, 1))
    parts = []
    for first in range(0, n_clips, per_chunk):
        block = counts[first:first + per_chunk].toarray()
        parts.append(np.asarray(statistic(np.power(1.0 + step, block)), dtype=float))
    moved = np.concatenate(parts, axis=0) if parts else np.zeros((0, len(estimate)))
    with np.errstate(invalid="ignore"):
        return (moved - estimate) / step


@dataclass
class Crossed:
    """Replicates of a statistic ``(K,)`` under each resampling scheme (and, when clips
    are random, each clip's influence ``(C, K)`` on it)."""

    estimate: np.ndarray
    participants: np.ndarray
    clips: np.ndarray
    observations: np.ndarray
    design: Design
    both: np.ndarray | None = None
    influence: np.ndarray | None = None

    def clip_df(self) -> np.ndarray:
        """Return per value the clips' degrees of freedom: ``m_s - 1`` summed over the
        strata whose clips move it (all strata, ``C - S``, without influences; 0 when no
        such stratum has two clips: the clips' variance cannot be estimated). A
        difference of two sources rests on those two sources' clips only, whatever
        other sources (a hidden reference, an anchor) the study shows. A source trained
        with several seeds counts its seeds, not its clips (``seeds - 1``)."""
        d = self.design
        sizes = np.bincount(d.unit_strata)
        every = float(d.n_resampled - len(np.unique(d.unit_strata)))
        if self.influence is None or not len(self.influence):
            return np.full(len(self.estimate), every)
        # A unit's influence: its clips' together (a seed's weight scales all its clips).
        influence = np.asarray(_indicator(d.units, d.n_resampled) @ np.nan_to_num(self.influence))
        strata = d.unit_strata
        centred = influence - _stratum_means(influence, strata, len(sizes))[strata]
        spread = _stratum_sums(centred ** 2, strata, len(sizes))  # (S, K)
        scale = np.maximum(spread.sum(axis=0), np.finfo(float).tiny)
        involved = spread > 1e-9 * scale
        return (np.maximum(sizes - 1, 0)[:, None] * involved).sum(axis=0).astype(float)

    def contrast(self, matrix) -> "Crossed":
        """Return the replicates of ``matrix @ statistic`` (``matrix`` ``(L, K)``)."""
        matrix = np.asarray(matrix, dtype=float)

        def apply(samples):
            if samples is None:
                return None
            with np.errstate(invalid="ignore"):
                return samples @ matrix.T

        return Crossed(matrix @ self.estimate, apply(self.participants), apply(self.clips),
                       apply(self.observations), self.design, apply(self.both),
                       apply(self.influence))

    def variances(self) -> dict:
        """Return ``V_p``, ``V_c``, ``V_obs``, the clip part, the combined ``V`` and ``df``,
        each ``(K,)``."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a value NaN in every replicate
            v_p = np.nanvar(self.participants, axis=0, ddof=1)
            v_c = np.nanvar(self.clips, axis=0, ddof=1)
            v_obs = np.nanvar(self.observations, axis=0, ddof=1)
        m, k = self.design.m, self.design.clips_per_unit
        if np.isfinite(m):
            # m clips drawn from m shrink their variance by (m - 1) / m; each of a unit's k
            # clips carries its answers' noise once more.
            clip_part = np.maximum(v_c * m / (m - 1) - k * v_obs, 0.0)
        else:
            clip_part = np.zeros_like(v_p)
        total = v_p + clip_part
        df_p = max(self.design.n_participants - 1, 1)
        df_c = self.clip_df()
        # A sum of two variance estimates with df_p and df_c degrees of freedom: the fewer
        # of the two (Hsu's bound, as for Welch's test) keeps the interval's level whatever
        # the true share of each. Satterthwaite's formula on the estimated shares does not:
        # when the clips' part happens to come out small it gives both a small variance
        # and many degrees of freedom (measured with 2 clips per source: coverage 0.88).
        # That holds for a clips' part estimated as 0 too: from one degree of freedom per
        # source it comes out 0 by chance also when clips vary, so the bound applies
        # whenever the clips were redrawn (their replicates vary), not only when the
        # estimate is positive (with P - 1 then, coverage 0.92-0.93 where 2 clips vary
        # little, docs/STATISTICS.md). Fixed clips (no clip replicates): P - 1.
        df = np.where((v_c > 0) & (df_c > 0), np.minimum(float(df_p), df_c), float(df_p))
        return {"participants": v_p, "clips": v_c, "observations": v_obs,
                "clip_part": clip_part, "total": total, "df": df}

    def summary(self, confidence: float = 0.95, null: float = 0.0, bounds=None) -> pd.DataFrame:
        """Return per value ``estimate``, ``se``, ``df``, ``ci_low``, ``ci_high`` (t
        interval of the combined variance, cut to ``bounds`` such as ``(0, 1)`` for a
        share), ``p`` (t test against ``null``) and the shares of its variance from
        ``participants``, ``clips`` and ``residual``."""
        parts = self.variances()
        se = np.sqrt(parts["total"])
        quantile = scipy_stats.t.ppf(0.5 + confidence / 2, parts["df"])
        with np.errstate(invalid="ignore", divide="ignore"):
            t = (self.estimate - null) / se
            p = 2 * scipy_stats.t.sf(np.abs(t), parts["df"])
            residual = np.minimum(parts["observations"], parts["participants"])
            shares = np.stack([parts["participants"] - residual, parts["clip_part"], residual])
            shares = shares / parts["total"]
        low, high = self.estimate - quantile * se, self.estimate + quantile * se
        if bounds is not None:
            low, high = np.clip(low, *bounds), np.clip(high, *bounds)
        return pd.DataFrame({
            "estimate": self.estimate, "se": se, "df": parts["df"], "ci_low": low, "ci_high": high,
            "p": np.where(se > 0, p, np.nan),
            "share_participants": shares[0], "share_clips": shares[1], "share_residual": shares[2],
        })

    def percentile(self, scheme: str = "participants", confidence: float = 0.95):
        """Return the percentile interval ``(low, high)`` of one scheme's replicates."""
        tail = 100 * (1 - confidence) / 2
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return tuple(np.nanpercentile(getattr(self, scheme), [tail, 100 - tail], axis=0))


def bootstrap(design: Design, statistic, config, both: bool = False) -> Crossed:
    """Return the :class:`Crossed` replicates of ``statistic``.

    ``statistic(weights)`` takes ``(B, N)`` unit weights and returns ``(B, K)``; the
    estimate is its value at weights of one. ``config`` gives ``bootstrap`` (replicates
    per scheme), ``seed`` and ``random_clips``: when false the clips are taken as the
    whole population of interest (no clip resampling: intervals over participants only,
    which hold for these clips). ``both`` also draws participants and clips at once (the
    pure two-way bootstrap, for comparison).
    """
    repeats, seed = config.bootstrap, config.seed
    estimate = np.asarray(statistic(np.ones((1, design.n_units))), dtype=float)[0]
    rng = np.random.default_rng(seed)
    if repeats <= 0 or design.n_participants < 2:
        empty = np.full((0, len(estimate)), np.nan)
        return Crossed(estimate, empty, empty, empty, design, empty if both else None)
    participants = _replicates(design, statistic, "participants", repeats, rng)
    if getattr(config, "random_clips", True):
        clips = _replicates(design, statistic, "clips", repeats, rng)
        observations = _replicates(design, statistic, "observations", repeats, rng)
    else:
        clips = observations = np.zeros_like(participants)
    extra = _replicates(design, statistic, "both", repeats, rng) if both else None
    influence = (clip_influence(design, statistic, estimate)
                 if getattr(config, "random_clips", True) else None)
    return Crossed(estimate, participants, clips, observations, design, extra, influence)


def _stratum_sums(values, strata, n_strata: int) -> np.ndarray:
    """Return ``(S, K)`` sums of the rows of ``values`` ``(C, K)`` per stratum."""
    return np.asarray(_indicator(strata, n_strata) @ values)


def _stratum_means(values, strata, n_strata: int) -> np.ndarray:
    """Return ``(S, K)`` means of the rows of ``values`` ``(C, K)`` per stratum."""
    sizes = np.maximum(np.bincount(strata, minlength=n_strata), 1)
    return _stratum_sums(values, strata, n_strata) / sizes[:, None]


def ratio(values, groups, n_groups: int, base=None):
    """Return a statistic: per group, the weighted mean of ``values`` over units (``base``
    weights, e.g. ``1 / n`` to count each participant once, times the replicate's)."""
    values = np.asarray(values, dtype=float)
    groups = np.asarray(groups, dtype=np.int64)
    base = np.ones(len(values)) if base is None else np.asarray(base, dtype=float)
    keep = groups >= 0
    indicator = sparse.csr_matrix((base[keep], (np.flatnonzero(keep), groups[keep])),
                                  shape=(len(values), n_groups))
    weighted = indicator.multiply(values[:, None]).tocsr()

    def finish(sums):
        with np.errstate(invalid="ignore", divide="ignore"):
            return sums[:, :n_groups] / sums[:, n_groups:]

    return Linear(sparse.hstack([weighted, indicator]), finish)


def clip_log_odds(values, clips, groups, n_groups: int, continuity: float = 0.5):
    """Return a statistic: per group, the mean over its clips of each clip's empirical
    log-odds ``log((k + c) / (n - k + c))`` of ``values`` (0/1 per unit; ``k`` the
    weighted ones, ``n`` the weighted units of the clip, ``c`` ``continuity``), each clip
    weighed by its units ``n``.

    A share pooled over a few clips is a mean of bounded clip rates; where clips vary
    much those rates pile up near 0 and 1, and a t test on 2 + 2 of them rejects too
    often (docs/STATISTICS.md). On the log-odds scale a clip's effect is close to normal
    (it is normal in the logistic model), so the t test of a difference of these means
    keeps its level. ``clips`` ``(N,)`` codes ``0..C-1``; ``groups`` ``(N,)`` codes
    ``0..n_groups-1`` (``-1``: left out), one per clip."""
    values = np.asarray(values, dtype=float)
    clips = np.asarray(clips, dtype=np.int64)
    groups = np.asarray(groups, dtype=np.int64)
    keep = groups >= 0
    n_clips = int(clips.max()) + 1 if len(clips) else 0
    group_of_clip = np.full(n_clips, -1, dtype=np.int64)
    group_of_clip[clips[keep]] = groups[keep]
    shown = np.flatnonzero(group_of_clip >= 0)
    rows = np.flatnonzero(keep)
    column = np.searchsorted(shown, clips[keep])
    width = len(shown)
    ones = sparse.csr_matrix((values[keep], (rows, column)), shape=(len(values), width))
    units = sparse.csr_matrix((np.ones(len(rows)), (rows, column)), shape=(len(values), width))
    to_group = _indicator(group_of_clip[shown], n_groups).T.toarray()  # (C, G)

    def finish(sums):
        k, n = sums[:, :width], sums[:, width:]
        with np.errstate(invalid="ignore", divide="ignore"):
            logit = np.log((k + continuity) / (n - k + continuity))
            logit = np.where(n > 0, logit, 0.0)
            return (n * logit) @ to_group / (n @ to_group)

    return Linear(sparse.hstack([ones, units]), finish)


def pair_matrix(names) -> tuple[np.ndarray, list[tuple]]:
    """Return the ``(pairs, K)`` contrast matrix of every difference ``a - b`` and the pairs."""
    pairs = list(itertools.combinations(range(len(names)), 2))
    matrix = np.zeros((len(pairs), len(names)))
    for row, (a, b) in enumerate(pairs):
        matrix[row, a], matrix[row, b] = 1.0, -1.0
    return matrix, [(names[a], names[b]) for a, b in pairs]


def differences(result: Crossed, names, confidence: float = 0.95) -> pd.DataFrame:
    """Return the table of every difference ``a - b`` between ``names`` (the values of
    ``result``): estimate, crossed interval, t test with Holm's correction, variance
    shares."""
    matrix, pairs = pair_matrix(names)
    table = result.contrast(matrix).summary(confidence)
    table.insert(0, "b", [b for _, b in pairs])
    table.insert(0, "a", [a for a, _ in pairs])
    table = table.rename(columns={"estimate": "difference"})
    table["p_holm"] = holm(table["p"])
    return table


def scores(result: Crossed, names, confidence: float = 0.95) -> pd.DataFrame:
    """Return ``score``, ``ci_low``, ``ci_high`` and the variance shares per name."""
    table = result.summary(confidence)
    table.index = pd.Index(list(names), name="source")
    return table.rename(columns={"estimate": "score"})[
        ["score", "ci_low", "ci_high", "se", "df", "share_participants", "share_clips",
         "share_residual"]]


def clips_per_source(rows: pd.DataFrame, clip: str = "stimulus", condition: str = "action") -> pd.DataFrame:
    """Return per source the number of clips and the fewest and most per condition."""
    by = ["source", condition] if condition in rows.columns else ["source"]
    per = rows.groupby(by, observed=True)[clip].nunique()
    frame = pd.DataFrame({
        "n_clips": rows.groupby("source", observed=True)[clip].nunique(),
        "fewest_per_condition": per.groupby(level="source").min(),
        "most_per_condition": per.groupby(level="source").max(),
    })
    frame.index.name = "source"
    return frame


def clip_warnings(table: pd.DataFrame, clips: pd.DataFrame) -> list[str]:
    """Return a sentence per difference of ``table`` (from :func:`differences`) whose
    variance comes mostly from the clips."""
    notes = []
    for row in table.itertuples():
        if np.isfinite(row.share_clips) and row.share_clips > CLIP_DOMINANCE:
            n = int(clips["n_clips"].reindex([row.a, row.b]).fillna(0).sum())
            notes.append(
                f"{row.share_clips:.0%} of the uncertainty of {row.a} - {row.b} comes from the "
                f"choice of clips: this difference may be about these {n} clips, not the method: "
                f"add clips, not participants")
    return notes


# Fewer clip degrees of freedom (clips less strata) than this: the clips' variance is
# rough, and docs/STATISTICS.md measured intervals below their level there.
FEW_CLIP_DF = 4


def one_clip_note(design: Design, fewest: float | None = None) -> str | None:
    """Return a note when some stratum has a single clip (its variance is unknown), or
    when the clips give fewer than :data:`FEW_CLIP_DF` degrees of freedom: in all
    (``C - S``), or ``fewest`` for some difference (the clips of the two sources it
    compares, :meth:`Crossed.clip_df`)."""
    sizes = design.units_per_stratum
    if np.all(sizes >= 2):
        groups = len(sizes)
        df = design.n_resampled - groups
        if df >= FEW_CLIP_DF and (fewest is None or fewest >= FEW_CLIP_DF):
            return None
        what = (f"{design.n_clips} clips in {design.n_strata} source-and-condition groups"
                if not design.n_seeds else
                f"{design.n_resampled} resampled units in {groups} groups: "
                f"{design.n_seeds} training seeds and {design.n_resampled - design.n_seeds} clips")
        rests = (f"the clips' variance rests on {df} {'degree' if df == 1 else 'degrees'} of "
                 f"freedom ({what})" if df < FEW_CLIP_DF else
                 f"the clips' variance of a difference rests on as few as {int(fewest)} "
                 f"{'degree' if int(fewest) == 1 else 'degrees'} of freedom (the clips of the two "
                 f"sources it compares)")
        return (f"{rests}: the intervals are rough and may hold less often than stated (with 2 "
                f"clips per source, 95 % intervals held as rarely as 0.92 of the time in simulations, "
                f"docs/STATISTICS.md); add clips (at least 4 per source and condition) for "
                f"firmer verdicts")
    if design.n_seeds:
        return (f"{int(np.sum(sizes < 2))} of {len(sizes)} groups of resampled clips or training "
                f"seeds have a single one: how much they vary cannot be estimated there, so the "
                f"intervals hold for these clips and checkpoints only; show at least 2 clips per "
                f"source and condition, and train 3 or more seeds per method")
    return (f"{int(np.sum(sizes < 2))} of {len(sizes)} source-and-condition groups have a single "
            f"clip: how much clips vary cannot be estimated there, so the intervals hold for "
            f"these clips only; show at least 2 (better 8) clips per source and condition")


def methods_text(design: Design, config) -> str:
    """Return how intervals and tests were obtained, for the methods paragraph."""
    repeats, confidence = config.bootstrap, config.confidence
    if repeats <= 0:
        return "no intervals or tests were computed (the bootstrap was switched off)"
    sizes = design.clips_per_stratum
    fewest, most = int(sizes.min()), int(sizes.max())
    per = f"{fewest}" if fewest == most else f"{fewest} to {most}"
    if not getattr(config, "random_clips", True):
        return (f"{confidence:.0%} intervals and tests hold for these {design.n_clips} clips "
                f"({per} per source and condition) as the whole population of interest: "
                f"{repeats} bootstrap resamples of the {design.n_participants} participants "
                f"(with all their answers) give a t interval, and each difference's t test uses "
                f"the same standard error, Holm-corrected across pairs; they say nothing about "
                f"other clips of the same sources")
    return (f"{confidence:.0%} intervals and tests treat participants and clips as random: "
            f"{repeats} bootstrap resamples of the {design.n_participants} participants "
            f"(with all their answers) and, separately, {repeats} of the {design.n_clips} clips "
            f"(drawn within their source and condition, {per} {'clip' if most == 1 else 'clips'} "
            f"each) give the two "
            f"variances, less the single answers' noise they both contain (answers resampled "
            f"among those to the same clips); the interval is a t interval of their sum with "
            f"the fewer of the participants' and the clips' degrees of freedom (of the clips of "
            f"the sources compared), and each "
            f"difference's t test uses the same standard error, Holm-corrected across pairs"
            + _seeds_text(design))


def _seeds_text(design: Design) -> str:
    """Return the methods clause on training seeds resampled whole, or ``""``."""
    if not design.n_seeds:
        return ""
    strata = np.unique(design.unit_strata[design.seeded])
    per = np.bincount(design.unit_strata[design.seeded])[strata]
    fewest, most = int(per.min()), int(per.max())
    count = f"{fewest}" if fewest == most else f"{fewest} to {most}"
    return (f"; for the {plural_sources(len(strata))} whose clips come from several training "
            f"seeds ({count} each), the clips' resamples redraw whole training seeds with all "
            f"their clips instead, so those intervals include how much the method varies from "
            f"one training to the next (the seeds' degrees of freedom, seeds less one per source)")


def plural_sources(n: int) -> str:
    return "source" if n == 1 else f"{n} sources"


def worth_statistic(orders, n_items: int, prior: float | None = None):
    """Return a statistic: the Plackett-Luce (Bradley-Terry for pairs) log-worths, centred,
    of ``orders`` ``(N, m)`` (one ordering per unit, best first, ``-1`` padded), refitted
    under each replicate's unit weights."""
    orders = np.asarray(orders, dtype=np.int64)
    options = {} if prior is None else {"prior": prior}
    if len(orders) < 2:  # nothing to redraw: the one fit, as often as asked
        data = worth.rankings(orders, np.arange(len(orders)), n_items, len(orders))
        theta = worth.bootstrap(data, 0, **options)["theta"]
        return lambda weights: np.tile(theta, (len(weights), 1))
    choices, per_unit = worth.choice_counts(orders, n_items)
    start = worth.refit(choices, np.asarray(per_unit.sum(axis=0)), **options)

    def finish(counts):
        return worth.refit(choices, counts, start=start, **options)

    return Linear(per_unit, finish)


@dataclass
class Report:
    """What a type's analysis shows of a crossed bootstrap of per-source values."""

    scores: pd.DataFrame
    differences: pd.DataFrame
    clips: pd.DataFrame
    notes: list
    method: str


def report(result: Crossed, names, rows: pd.DataFrame, config) -> Report:
    """Return the scores, differences (Holm), clip counts, warnings and methods sentence of
    ``result``, a crossed bootstrap of one value per source of ``names``."""
    differences_table = differences(result, names, config.confidence)
    clips = clips_per_source(rows)
    notes = []
    if getattr(config, "random_clips", True):
        notes = clip_warnings(differences_table, clips)
        fewest = result.contrast(pair_matrix(names)[0]).clip_df() if len(names) > 1 else None
        single = one_clip_note(result.design, None if fewest is None or not len(fewest)
                               else float(np.min(fewest)))
        if single:
            notes.append(single)
    return Report(scores(result, names, config.confidence), differences_table, clips, notes,
                  methods_text(result.design, config))


DIFFERENCE_COLUMNS = ["a", "b", "difference", "ci_low", "ci_high", "se", "df", "p", "p_holm",
                      "share_participants", "share_clips", "share_residual"]


def group_means(rows: pd.DataFrame, value: str, config, by=("source",), base=None):
    """Return the crossed bootstrap of the mean of column ``value`` per group of ``by``
    (every row a unit; ``base`` row weights, e.g. to count each participant once) and
    the groups (sorted)."""
    by = list(by)
    groups = rows.groupby(by, observed=True, sort=True).size().index
    keys = pd.MultiIndex.from_frame(rows[by]) if len(by) > 1 else pd.Index(rows[by[0]])
    statistic = ratio(rows[value].to_numpy(dtype=float), groups.get_indexer(keys), len(groups), base)
    return bootstrap(design(rows), statistic, config), groups


def intervals(result: Crossed, groups, config, bounds=None) -> pd.DataFrame:
    """Return ``score``, ``ci_low``, ``ci_high`` of ``result`` indexed by ``groups``."""
    table = result.summary(config.confidence, bounds=bounds)
    return pd.DataFrame({"score": table["estimate"].to_numpy(), "ci_low": table["ci_low"].to_numpy(),
                         "ci_high": table["ci_high"].to_numpy()}, index=groups)
