"""Bonuses: who gets how much, checked before anything is sent to Prolific.

Prolific's bulk bonus ("Set up bonuses", then "Pay bonuses") takes lines
``<participant_id>,<amount>`` with the amount in the study's currency as a decimal
(``4.25`` is 4.25, and ``30`` is 30.00, not 30 cents). Here amounts are kept in cents
and written out in Prolific's form, so a cents/units mix-up cannot reach it.
"""

from __future__ import annotations

import csv
import re
from decimal import Decimal, InvalidOperation
from pathlib import Path

from studyapp.crowd.platforms.prolific import PROLIFIC_ID

PAYABLE = ("APPROVED", "AWAITING REVIEW")


class BonusError(ValueError):
    """The bonus list is not usable; the message lists every bad line."""


def cents_of(text: str) -> int:
    """Return the cents of an amount written as Prolific wants it (``4.25``); ValueError."""
    if not re.fullmatch(r"\d+(\.\d{1,2})?", text.strip()):
        raise ValueError(f"{text!r} is not an amount such as 4.25 (the study's currency, "
                         f"at most 2 decimals)")
    return int(Decimal(text.strip()) * 100)


def amount_text(cents: int) -> str:
    return f"{Decimal(cents) / 100:.2f}"


def read_csv(path, max_cents: int) -> dict[str, int]:
    """Return ``{Prolific id: cents}`` from a file of ``participant_id,amount`` lines (a
    header line is allowed). Raise :class:`BonusError` listing every bad line, so that
    nothing is paid from a file with a mistake in it."""
    path = Path(path)
    try:
        rows = list(csv.reader(path.read_text(encoding="utf-8-sig").splitlines()))
    except (OSError, UnicodeDecodeError) as error:
        raise BonusError(f"{path}: cannot read it ({error})") from None
    bonuses, problems = {}, []
    for number, row in enumerate(rows, start=1):
        cells = [c.strip() for c in row]
        if not any(cells):
            continue
        if number == 1 and cells and not PROLIFIC_ID.match(cells[0].lower()):
            continue  # a header such as participant_id,amount
        if len(cells) != 2:
            problems.append(f"line {number}: {len(cells)} column(s); write "
                            f"participant_id,amount (e.g. 60ffe5c8371090c7041d43f8,0.50)")
            continue
        pid, amount = cells[0].lower(), cells[1]
        if not PROLIFIC_ID.match(pid):
            problems.append(f"line {number}: {cells[0]!r} is not a Prolific participant id "
                            f"(24 hex digits)")
            continue
        try:
            cents = cents_of(amount)
        except (ValueError, InvalidOperation) as error:
            problems.append(f"line {number}: {error}")
            continue
        if not 0 < cents <= max_cents:
            problems.append(f"line {number}: {amount} is not between 0.01 and "
                            f"{amount_text(max_cents)} (--max-amount-cents raises the limit)")
            continue
        if pid in bonuses:
            problems.append(f"line {number}: {pid} appears twice")
            continue
        bonuses[pid] = cents
    if problems:
        raise BonusError(f"{path}: nothing was paid; fix these lines: " + "; ".join(problems))
    if not bonuses:
        raise BonusError(f"{path}: no bonus lines in it")
    return bonuses


def csv_bonuses(bonuses: dict[str, int]) -> str:
    """Return Prolific's ``csv_bonuses`` text."""
    return "\n".join(f"{pid},{amount_text(cents)}" for pid, cents in bonuses.items())


def check_took_part(bonuses: dict[str, int], submissions: list[dict]) -> None:
    """Raise :class:`BonusError` naming the ids without a submission Prolific pays
    bonuses on (it answers 400 for them)."""
    status = {str(s.get("participant_id", "")).lower(): s.get("status") for s in submissions}
    missing = [pid for pid in bonuses if pid not in status]
    unpaid = [f"{pid} ({status[pid]})" for pid in bonuses
              if pid in status and status[pid] not in PAYABLE]
    problems = []
    if missing:
        problems.append(f"no submission in this study: {', '.join(missing)}")
    if unpaid:
        problems.append(f"submission not approved or awaiting review: {', '.join(unpaid)}")
    if problems:
        raise BonusError("nothing was paid; " + "; ".join(problems))


def paid_before(client, bonuses: dict[str, int], submissions: list[dict]) -> dict[str, list]:
    """Return ``{Prolific id: bonus payments in cents}`` of those already given a bonus in
    this study (each submission's ``bonus_payments``; a bonus being paid right now may
    not show yet: Prolific pays them asynchronously)."""
    by_pid = {str(s.get("participant_id", "")).lower(): s for s in submissions}
    out = {}
    for pid in bonuses:
        detail = client.submission(by_pid[pid]["id"])
        payments = (detail or {}).get("bonus_payments") or []
        if payments:
            out[pid] = payments
    return out
