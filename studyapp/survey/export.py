"""Export a study's answers as tables for :mod:`analysis`: one row per judgement
(:func:`responses_frame`) and one row per participant (:func:`participants_frame`)."""

from __future__ import annotations

import pandas as pd
from django.core.management.base import CommandError
from django.db import DatabaseError
from django.db.models import Count

from analysis.tables import INTEGER_COLUMNS, RESPONSE_COLUMNS

from .forms import DemographicsForm
from .models import Participant, Study, Trial, TrialItem

# Response-table column -> TrialItem lookup, for the columns read straight from the database.
LOOKUPS = {
    "participant": "trial__participant_id",
    "participant_seed": "trial__participant__seed",
    "trial": "trial__index",
    "trial_id": "trial_id",
    "action": "trial__action",
    "stimulus": "stimulus_id",
    "stimulus_token": "stimulus__token",
    "source": "stimulus__source",
    "motion_hash": "stimulus__motion_hash",
    "video_hash": "stimulus__video_hash",
    "duration": "stimulus__duration",
    "position": "position",
    "trial_kind": "trial__kind",
    "is_catch": "stimulus__is_catch",
    "rank": "rank",
    "rating": "rating",
    "judged_real": "judged_real",
    "choice": "trial__choice",
    "catch_passed": "trial__catch_passed",
    "plays": "plays",
    "time_ms": "trial__time_ms",
    "shown_at": "trial__shown_at",
    "answered_at": "trial__answered_at",
}
EXTERNAL_IDS = "trial__participant__external_ids"
COMPLETED_AT = "trial__participant__completed_at"
# Answer columns of every study type; appended if the response table does not list them.
ANSWER_COLUMNS = (
    "duration", "trial_kind", "is_catch", "rank", "rating", "judged_real", "choice",
    "catch_passed",
)
NULLABLE_BOOLEANS = ("judged_real", "catch_passed")


def get_study(slug: str) -> Study:
    """Return the study called ``slug``, or raise a ``CommandError`` listing the slugs."""
    try:
        return Study.objects.get(slug=slug)
    except DatabaseError as error:
        raise CommandError(f"Cannot read the study database ({error}); run migrate?") from None
    except Study.DoesNotExist:
        slugs = sorted(Study.objects.values_list("slug", flat=True))
        known = f"known studies: {', '.join(slugs)}" if slugs else "there are no studies yet"
        raise CommandError(f"Unknown study {slug!r}; {known}.") from None


def responses_frame(study: Study) -> pd.DataFrame:
    """Return one row per judgement of ``study``, by participant, trial, position.

    A judgement is a clip of an answered trial, whatever the study type; practice
    trials are left out, catch and repeated trials kept with their ``trial_kind``.
    Reference and standard example clips are never trial items, so never rows.
    Crowd-platform ids (``Participant.external_ids``) become columns right after
    ``participant``; times are ISO 8601 strings.
    """
    items = TrialItem.objects.filter(trial__participant__study=study)
    n_items = dict(items.order_by().values_list("trial_id").annotate(n=Count("id")))
    rows = list(
        items.filter(trial__answered_at__isnull=False)
        .exclude(trial__kind=Trial.Kind.PRACTICE)
        .order_by("trial__participant_id", "trial__index", "position")
        .values(EXTERNAL_IDS, COMPLETED_AT, *LOOKUPS.values())
    )
    external = sorted({key for row in rows for key in (row[EXTERNAL_IDS] or {})})
    external = [key if key not in RESPONSE_COLUMNS else f"external_{key}" for key in external]
    records = []
    for row in rows:
        record = {name: row[lookup] for name, lookup in LOOKUPS.items()}
        for key, value in (row[EXTERNAL_IDS] or {}).items():
            record[key if key not in RESPONSE_COLUMNS else f"external_{key}"] = value
        record.update(
            study=study.slug,
            study_type=study.study_type,
            n_items=n_items[row["trial_id"]],
            completed=row[COMPLETED_AT] is not None,
            shown_at=_iso(record["shown_at"]),
            answered_at=_iso(record["answered_at"]),
        )
        records.append(record)

    columns = list(RESPONSE_COLUMNS) + [c for c in ANSWER_COLUMNS if c not in RESPONSE_COLUMNS]
    after = columns.index("participant") + 1
    columns[after:after] = external
    table = pd.DataFrame.from_records(records, columns=columns)
    for name in set(INTEGER_COLUMNS) | {"rating"}:
        table[name] = table[name].astype("Int64")
    for name in NULLABLE_BOOLEANS:
        table[name] = table[name].astype("boolean")
    for name in ("completed", "is_catch"):
        table[name] = table[name].astype(bool)
    return table


PARTICIPANT_COLUMNS = (
    "study",
    "participant",
    "participant_seed",
    "started",
    "consented_at",
    "completed",
    "completed_at",
    "completion_code",
    "n_judgements",
    "n_catch",
    "failed_catch",
    "n_repeat",
    "inconsistent_repeats",
)


def participants_frame(study: Study) -> pd.DataFrame:
    """Return one row per participant of ``study``: ids, times, checks, demographics.

    ``failed_catch`` counts failed catch trials (the usual exclusion rule: any),
    ``inconsistent_repeats`` repeated trials answered differently. Crowd-platform ids
    follow ``participant``; the demographic answers (blank when not asked or not
    given) come last.
    """
    participants = list(Participant.objects.with_checks().filter(study=study).order_by("pk"))
    external = sorted({key for p in participants for key in (p.external_ids or {})})
    external = [k if k not in PARTICIPANT_COLUMNS else f"external_{k}" for k in external]
    demographic = list(DemographicsForm.base_fields)
    records = []
    for p in participants:
        record = {
            "study": study.slug,
            "participant": p.pk,
            "participant_seed": p.seed,
            "started": _iso(p.created_at),
            "consented_at": _iso(p.consented_at),
            "completed": p.completed_at is not None,
            "completed_at": _iso(p.completed_at),
            "completion_code": p.completion_code,
            "n_judgements": p.n_judgements,
            "n_catch": p.n_catch,
            "failed_catch": p.failed_catch,
            "n_repeat": p.n_repeat,
            "inconsistent_repeats": p.inconsistent_repeats,
        }
        for key, value in (p.external_ids or {}).items():
            record[key if key not in PARTICIPANT_COLUMNS else f"external_{key}"] = value
        record.update({name: (p.demographics or {}).get(name, "") for name in demographic})
        records.append(record)
    columns = list(PARTICIPANT_COLUMNS)
    columns[2:2] = external
    table = pd.DataFrame.from_records(records, columns=columns + demographic)
    for name in ("participant", "participant_seed", *PARTICIPANT_COLUMNS[-5:]):
        table[name] = table[name].astype("Int64")
    table["completed"] = table["completed"].astype(bool)
    return table


def _iso(moment) -> str | None:
    return moment.isoformat() if moment is not None else None
