"""Analyse a study's response table: checks, exclusions, the study type's statistics,
agreement between raters, attention checks, and a methods paragraph.

    result = analyse(table)            # table: one row per judgement (analysis.tables)
    write_report(result, "out/")       # analysis.report
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from analysis import exclusions
from analysis.agreement import MIN_AGREEMENT_UNITS, few_units_text, krippendorff_alpha
from analysis.stats import small_sample_note
from analysis.registry import Analysis, Table, get_analysis
from analysis.tables import AnalysisError, as_boolean

TRIAL_KINDS = ("main", "catch", "instructed", "repeat")


@dataclass(frozen=True)
class AnalysisConfig:
    """Choices of an analysis; the report states them."""

    exclusions: bool = True
    min_time_factor: float = 1.0
    max_failed_catch: int = 0
    max_failed_repeats: int | None = None  # None: counted, not applied
    completed_only: bool = False
    bootstrap: int = 1000
    confidence: float = 0.95
    seed: int = 0
    real_source: str = "real"
    # Clips as a random sample of each source's motions (the default: verdicts about the
    # sources), or as the whole population of interest (verdicts about these clips only).
    random_clips: bool = True
    # Also fit the mixed models of analysis.mixed where the type has one (seconds per fit).
    mixed_models: bool = False
    # The study type's own options (Study.options), for analyses that follow them (a
    # screening threshold); empty when a table is analysed without its study.
    type_options: dict = field(default_factory=dict)
    # The study's own design (Study fields: practice, catch_trials, instructed_checks,
    # repeat_trials), for the methods paragraph;
    # empty when a table is analysed without its study (the table then says what it holds).
    study_options: dict = field(default_factory=dict)

    def __post_init__(self):
        if not 0 < self.confidence < 1:
            raise AnalysisError(f"confidence must lie between 0 and 1; got {self.confidence}")
        if self.min_time_factor < 0:
            raise AnalysisError(f"min_time_factor must be 0 or more; got {self.min_time_factor}")
        if self.bootstrap < 0 or self.max_failed_catch < 0 or (self.max_failed_repeats or 0) < 0:
            raise AnalysisError("bootstrap, max_failed_catch and max_failed_repeats must be 0 "
                                "or more")


@dataclass
class StudyResult:
    """Everything a report needs: the study type's analysis and the shared checks."""

    study: str
    study_type: str
    config: AnalysisConfig
    analysis: Analysis
    exclusions: pd.DataFrame
    agreement: dict
    counts: dict
    quality: pd.DataFrame
    demographics: pd.DataFrame | None = None
    notes: list[str] = field(default_factory=list)
    design: str = ""
    criterion: str = ""  # the question analysed, when a trial asked several
    blindness: dict | None = None  # the blindness audit of the served clips, when run
    appendix: list[Table] = field(default_factory=list)  # tables the caller adds (e.g. stimuli)
    sources_text: list[str] = field(default_factory=list)  # where the clips come from (caller's)

    @property
    def tables(self) -> list[Table]:
        """Return every table of the report, the study type's first."""
        extra = [
            Table("exclusions", "Exclusions (main-trial judgements)", self.exclusions),
            Table("agreement", "Inter-rater agreement (Krippendorff's alpha)",
                  pd.DataFrame([self.agreement])),
        ]
        if not self.quality.empty:
            extra.append(Table("attention", "Attention checks and repeated trials", self.quality))
        if self.demographics is not None and not self.demographics.empty:
            extra.append(Table("participants", "Participants", self.demographics))
        if self.blindness:
            rows = [{"told apart": label, **part} for label, part in self.blindness.items()]
            extra.append(Table(
                "blindness", "Blindness audit: per question and family of what a script is "
                "sent (delivery: sizes, headers, boxes, padding; content: true frame sizes, "
                "the player's joints; hashes of every delivery), a permutation test of "
                "cross-validated classifiers", pd.DataFrame(rows)))
        return self.analysis.tables + extra + self.appendix

    def summary(self) -> dict:
        """Return the content of ``summary.json``: per source score, interval and N, and the order."""
        sources = self.analysis.sources
        return {
            "study": self.study,
            "study_type": self.study_type,
            "criterion": self.criterion,
            "measure": self.analysis.measure,
            "confidence": self.config.confidence,
            "n_participants": self.counts["participants"],
            "n_judgements": self.counts["judgements"],
            "n_simulated": self.counts.get("simulated", 0),  # bots among the participants
            "order": [str(s) for s in sources.index],
            "sources": {
                str(source): {
                    "score": _number(row["score"]),
                    "ci": [_number(row["ci_low"]), _number(row["ci_high"])],
                    "n_participants": int(row["n_participants"]),
                    "n_judgements": int(row["n_judgements"]),
                }
                for source, row in sources.iterrows()
            },
            "tests": _jsonable(self.analysis.tests),
            "agreement": _jsonable(self.agreement),
            "exclusions": self.exclusions.to_dict("records"),
            "config": asdict(self.config),
            "blindness": _jsonable(self.blindness),
            "notes": self.notes,
        }

    def methods(self) -> str:
        """Return a methods paragraph a paper can adapt."""
        from analysis.writeup import methods_paragraph

        return methods_paragraph(self)


def criteria_of(table: pd.DataFrame) -> list[str]:
    """Return the criteria a table holds answers for, in the order they first appear
    (``[""]`` for a table without a ``criterion`` column: one question)."""
    if "criterion" not in table.columns or table["criterion"].isna().all():
        return [""]
    return list(dict.fromkeys(table["criterion"].dropna().astype(str)))


def analyse_all(table: pd.DataFrame, config: AnalysisConfig | None = None,
                participants: pd.DataFrame | None = None,
                study_type: str | None = None) -> list["StudyResult"]:
    """Return one :func:`analyse` result per criterion of ``table`` (the first first)."""
    return [analyse(table, config, participants, study_type, criterion)
            for criterion in criteria_of(table)]


def analyse(table: pd.DataFrame, config: AnalysisConfig | None = None,
            participants: pd.DataFrame | None = None, study_type: str | None = None,
            criterion: str | None = None) -> StudyResult:
    """Analyse ``table`` (one row per judgement) as its study type asks; see the module doc.

    ``participants`` is the optional per-participant table (demographics);
    ``study_type`` overrides the table's ``study_type`` column. A table answering
    several questions of the same clips (a ``criterion`` column) is analysed for one
    ``criterion`` (default: the first); :func:`analyse_all` does each.
    """
    config = config or AnalysisConfig()
    if table is None or len(table) == 0:
        raise AnalysisError("the study has no judgements yet; nothing to analyse")
    criteria = criteria_of(table)
    if criterion is None:
        criterion = criteria[0]
    if criterion not in criteria:
        raise AnalysisError(f"the table has no answers for criterion {criterion!r}; it has "
                            f"{', '.join(c for c in criteria if c) or 'one unnamed criterion'}")
    if criterion:
        table = table.loc[table["criterion"].astype(str) == criterion]
    study_type = study_type or _study_type(table)
    kind = get_analysis(study_type)
    rows, kept, main, excluded, notes = _excluded(table, config, kind)
    if main.empty:
        raise AnalysisError(
            "no answered main-trial judgements are left after exclusions "
            f"({_exclusion_text(excluded)}); try --no-exclusions to see them all"
        )
    sources = sorted(main["source"].astype(str).unique())
    if len(sources) < 2:
        raise AnalysisError(
            f"only one source ({sources[0]}) was judged: comparing sources needs at least two"
        )
    quality = _quality(rows, kept, main, kind)
    # Number the analysed participants 0..P-1: bootstraps resample exactly these.
    main = main.assign(pcode=pd.factorize(main["pcode"])[0])

    by_prompt = has_prompts(main)
    if by_prompt:
        # A prompts study's conditions are its prompts: per-action tables become per prompt.
        main = main.assign(action=main["prompt"].astype(str))
    analysis = kind.analyse(main, config)
    if by_prompt:
        analysis.tables = [per_prompt(t) for t in analysis.tables]
    values = kind.judgement_values(main)
    unit = "pair of stimuli" if kind.answer == "choice" else "stimulus"
    agreement = {"answer": kind.answer, "unit": unit,
                 **krippendorff_alpha(values["unit"], values["value"], kind.agreement_level,
                                      bootstrap=config.bootstrap, confidence=config.confidence,
                                      seed=config.seed)}
    if agreement["n_units"] == 0:
        notes.append("no stimulus was judged by two or more participants: agreement is undefined")
    elif agreement["n_units"] < MIN_AGREEMENT_UNITS:
        notes.append(few_units_text(agreement["n_units"]))
    counts = {
        "participants": int(main["pcode"].nunique()),
        "judgements": len(main),
        "trials": int(main["trial_key"].nunique()),
        "actions": int(main["action"].nunique()) if "action" in main.columns and not by_prompt
        else 0,
        "sources": sources,
        "participants_before": int(rows["pcode"].nunique()),
    }
    if by_prompt:
        counts["prompts"] = int(main["prompt"].nunique())
    counts.update(_checks(rows))
    counts["simulated"] = (int(main.loc[main["simulated"], "pcode"].nunique())
                           if "simulated" in main.columns else 0)
    small = small_sample_note(counts["participants"])
    if small:
        notes.append(small)
    demographics = None
    if participants is not None and len(participants):
        analysed = set(main["participant"].astype(str))
        demographics = _demographics(participants, analysed)
        counts["outcomes"] = _outcomes(participants)
    names = table["study"].dropna() if "study" in table.columns else pd.Series(dtype=object)
    study = str(names.iloc[0]) if len(names) else ""
    design = kind.describe(main, config)
    return StudyResult(study, study_type, config, analysis, excluded, agreement, counts, quality,
                       demographics, notes + analysis.notes,
                       design.replace("one action", "one text prompt") if by_prompt else design,
                       criterion)


def apply_exclusions(table: pd.DataFrame, config: AnalysisConfig | None = None,
                     study_type: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Return the answered main-trial judgements of ``table`` (one criterion's rows) that
    :func:`analyse` would analyse, its exclusion table (the shared rules and the study
    type's screening) and notes: the same rules, without the statistics (the admin's
    live dashboard counts exclusions as they happen)."""
    config = config or AnalysisConfig()
    kind = get_analysis(study_type or _study_type(table))
    _, _, main, excluded, notes = _excluded(table, config, kind)
    return main, excluded, notes


def _excluded(table, config, kind):
    """Return the prepared rows, those kept by the shared rules, the answered main-trial
    judgements analysed, the exclusion table and notes."""
    rows, notes = _prepare(table, kind)
    kept, excluded, exclusion_notes = exclusions.apply(rows, config)
    notes += exclusion_notes
    main = kept.loc[(kept["trial_kind"] == "main").to_numpy() & ~kept["is_catch"].to_numpy()]
    main, answer_notes = kind.answered(main)
    notes += answer_notes
    main, screened, screen_notes = kind.screen(main, config)
    notes += screen_notes
    return rows, kept, main, _with_screening(excluded, screened), notes


def has_prompts(rows: pd.DataFrame) -> bool:
    """Return whether the trials of ``rows`` showed text prompts (a ``prompt`` column with
    a prompt in every row)."""
    if "prompt" not in rows.columns or rows.empty:
        return False
    prompts = rows["prompt"]
    return bool(prompts.notna().all() and (prompts.astype(str).str.strip() != "").all())


def per_prompt(table: Table) -> Table:
    """Return a per-action table of a prompts study as the per-prompt table it is."""
    if "action" not in table.name and "action" not in table.frame.columns:
        return table
    frame = table.frame.rename(columns={"action": "prompt"})
    if "action" in (frame.index.names or []):
        frame = frame.rename_axis(index={"action": "prompt"})
    return Table(table.name.replace("action", "prompt"),
                 table.title.replace("per action", "per prompt"), frame, table.note)


def _with_screening(excluded: pd.DataFrame, screened: list[dict]) -> pd.DataFrame:
    """Return the exclusion table with the study type's own rules (``screened``, counted as
    the shared rules are) before its last row, "Analysed", which loses what they removed."""
    if not screened:
        return excluded
    analysed = excluded.iloc[-1].copy()
    for record in screened:
        if record["applied"] == "yes":
            for name in ("participants", "trials", "judgements"):
                analysed[name] -= record[name]
    rules = pd.DataFrame(screened, columns=excluded.columns)
    rules["excludes"] = rules["excludes"].astype(object).fillna("participants")
    return pd.concat([excluded.iloc[:-1], rules, analysed.to_frame().T], ignore_index=True)


def _study_type(table) -> str:
    if "study_type" not in table.columns or table["study_type"].isna().all():
        raise AnalysisError("the table has no study_type column: say which study type it is")
    types = sorted(table["study_type"].dropna().astype(str).unique())
    if len(types) > 1:
        raise AnalysisError(f"the table mixes study types ({', '.join(types)}): analyse one study at a time")
    return types[0]


def _prepare(table: pd.DataFrame, kind) -> tuple[pd.DataFrame, list[str]]:
    """Return the columns the analysis uses, typed, with participant and trial codes."""
    required = ("participant", "source", kind.answer) + tuple(getattr(kind, "required", ()))
    missing = [name for name in required if name not in table.columns]
    if not any(name in table.columns for name in ("trial_id", "trial")):
        missing.append("trial_id (or trial)")
    if missing:
        raise AnalysisError(
            f"a {kind.name} analysis needs the column(s) {', '.join(missing)}; "
            f"the table has: {', '.join(map(str, table.columns))}"
        )
    notes = []
    blank = table["participant"].isna() | table["source"].isna()
    if blank.any():
        notes.append(f"{int(blank.sum())} row(s) with no participant or source were left out")
        table = table.loc[~blank]
    wanted = ["participant", "action", "prompt", "stimulus", "source", "stimulus_role",
              "position", "n_items", kind.answer, *getattr(kind, "required", ()), "trial_kind",
              "is_catch", "catch_passed", "time_ms", "duration", "completed", "simulated",
              "training_seed"]
    rows = table[[name for name in dict.fromkeys(wanted) if name in table.columns]].copy()
    rows["pcode"] = pd.factorize(rows["participant"])[0]
    if "trial_id" in table.columns and table["trial_id"].notna().all():
        rows["trial_key"] = pd.factorize(table["trial_id"])[0]
    elif "trial" in table.columns and table["trial"].notna().all():
        trial = pd.to_numeric(table["trial"], errors="coerce").to_numpy()
        rows["trial_key"] = pd.factorize(rows["pcode"].to_numpy() * (np.nanmax(trial) + 1) + trial)[0]
    else:
        raise AnalysisError("some rows have no trial_id or trial: cannot tell the trials apart")
    if "stimulus" not in rows.columns or rows["stimulus"].isna().all():
        rows["stimulus"] = rows["source"].astype(str)
        if "action" in rows.columns:
            rows["stimulus"] += "/" + rows["action"].astype(str)
        notes.append("the table has no stimulus ids: agreement treats each source and action as one unit")
    if "trial_kind" in rows.columns:
        kinds = rows["trial_kind"].fillna("main").astype(str)
        unknown = sorted(set(kinds.unique()) - set(TRIAL_KINDS))
        if unknown:
            raise AnalysisError(f"unknown trial_kind {', '.join(unknown)}; expected {', '.join(TRIAL_KINDS)}")
        rows["trial_kind"] = kinds
    else:
        rows["trial_kind"] = "main"
    for name in ("is_catch", "catch_passed"):
        if name in rows.columns:
            rows[name] = as_boolean(rows[name], name)
        else:
            rows[name] = pd.array([pd.NA] * len(rows), dtype="boolean")
    rows["is_catch"] = rows["is_catch"].fillna(False).astype(bool)
    if "completed" in rows.columns:
        rows["completed"] = as_boolean(rows["completed"], "completed")
    if "simulated" in rows.columns:
        rows["simulated"] = as_boolean(rows["simulated"], "simulated").fillna(False).astype(bool)
    rows["source"] = rows["source"].astype(str)
    return rows, notes


def _quality(rows, kept, main, kind) -> pd.DataFrame:
    """Return catch-trial pass rates and the consistency of repeated trials."""
    records = []
    catch = rows.loc[rows["catch_passed"].notna() & (rows["trial_kind"] != "repeat")]
    if len(catch):
        trials = catch.groupby("trial_key")["catch_passed"].all()
        records.append({"check": "catch trials passed", "n": len(trials),
                        "participants": int(catch["pcode"].nunique()),
                        "value": float(trials.mean()),
                        "detail": f"{int(trials.sum())} of {len(trials)} catch trials"})
    repeats = kept.loc[kept["trial_kind"] == "repeat"]
    if len(repeats):
        repeats, _ = kind.answered(repeats)
        again = kind.judgement_values(repeats)
        first = kind.judgement_values(main).drop_duplicates(["participant", "unit"])
        pairs = again.merge(first, on=["participant", "unit"], suffixes=("_repeat", "_first"))
        if len(pairs):
            same = (pairs["value_repeat"].astype(str) == pairs["value_first"].astype(str)).mean()
            detail = f"{len(pairs)} repeated judgements compared with the first"
            if kind.agreement_level == "ordinal":
                gap = np.abs(pd.to_numeric(pairs["value_repeat"]) - pd.to_numeric(pairs["value_first"]))
                detail += f"; mean absolute difference {gap.mean():.2f}"
            records.append({"check": "repeated judgements identical", "n": len(pairs),
                            "participants": int(pairs["participant"].nunique()),
                            "value": float(same), "detail": detail})
    return pd.DataFrame(records, columns=["check", "n", "participants", "value", "detail"])


def _checks(rows: pd.DataFrame) -> dict:
    """Return how many catch, instructed and repeated trials the table holds, and how many
    participants had each (before exclusions): what the methods paragraph may describe."""
    out = {}
    for kind in ("catch", "instructed", "repeat"):
        trials = rows.loc[rows["trial_kind"] == kind]
        out[f"{kind}_trials"] = int(trials["trial_key"].nunique())
        out[f"{kind}_participants"] = int(trials["pcode"].nunique())
    return out


def simulated_mask(participants: pd.DataFrame) -> pd.Series:
    """Return which rows of a per-participant table are simulated participants (bots)."""
    if "simulated" not in participants.columns:
        return pd.Series(False, index=participants.index)
    return as_boolean(participants["simulated"], "simulated").fillna(False).astype(bool)


def _outcomes(participants: pd.DataFrame) -> dict:
    """Return how many participants of the per-participant table ended each way (its
    ``outcome`` column; blank: still taking part), and how many were simulated."""
    out = {"total": len(participants), "simulated": int(simulated_mask(participants).sum())}
    if "outcome" in participants.columns:
        ended = participants["outcome"].fillna("").astype(str).str.strip()
        out["by_outcome"] = {str(k): int(v) for k, v in ended.value_counts().items()}
    return out


# Columns of the per-participant table that are bookkeeping (or free text), not
# demographics a paragraph summarises.
_BOOKKEEPING = {"participant", "study", "started", "completed", "started_at", "completed_at",
                "consented_at", "n_judgements", "n_catch", "failed_catch", "n_repeat",
                "inconsistent_repeats", "seed", "participant_seed", "completion_code",
                "outcome", "simulated", "user_agent", "comments"}


def _demographics(participants: pd.DataFrame, analysed: set) -> pd.DataFrame:
    """Summarise each demographic column over the analysed participants who are people:
    simulated participants' answers (a bot's random age and gender) are counted, never
    summarised."""
    if "participant" in participants.columns:
        participants = participants.loc[participants["participant"].astype(str).isin(analysed)]
    simulated = simulated_mask(participants)
    records = [{"variable": "participants", "summary": str(len(participants))}]
    if simulated.any():
        records.append({"variable": "simulated participants (bots; not summarised)",
                        "summary": str(int(simulated.sum()))})
        participants = participants.loc[~simulated]
    for name in participants.columns:
        lowered = str(name).lower()
        if lowered in _BOOKKEEPING or lowered.endswith(("_id", "pid", "id")):
            continue
        values = participants[name].dropna()
        values = values[values.astype(str).str.strip() != ""]
        if values.empty:
            continue
        numbers = pd.to_numeric(values, errors="coerce")
        if numbers.notna().all():
            summary = (f"mean {numbers.mean():.1f}, SD {numbers.std(ddof=1):.1f}, "
                       f"range {numbers.min():g}-{numbers.max():g} (n={len(numbers)})")
        else:
            counts = values.astype(str).value_counts()
            summary = ", ".join(f"{k}: {v}" for k, v in counts.items())
        records.append({"variable": str(name), "summary": summary})
    return pd.DataFrame(records, columns=["variable", "summary"])


def _exclusion_text(excluded: pd.DataFrame) -> str:
    before = excluded.iloc[0]["judgements"]
    return f"{before} main-trial judgement(s) before exclusions"


def _number(value):
    value = float(value)
    return value if np.isfinite(value) else None


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, pd.DataFrame):
        return [_jsonable(r) for r in value.to_dict("records")]
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return _number(value)
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.bool_,)):
        return bool(value)
    return value
