"""The methods paragraph of a report: participants, exclusions, tests, agreement."""

from __future__ import annotations

from analysis.formatting import number
from analysis.stats import MIN_PARTICIPANTS


def methods_paragraph(result) -> str:
    """Return a paragraph describing how ``result`` (a ``StudyResult``) was obtained."""
    counts, config = result.counts, result.config
    sentences = []
    actions = f" of {counts['actions']} actions" if counts["actions"] > 1 else ""
    if counts.get("prompts", 0) > 1:
        actions = f" of {counts['prompts']} text prompts"
    sentences.append(
        f"{counts['participants']} participants gave {counts['judgements']} judgements in "
        f"{counts['trials']} trials{actions}, comparing {len(counts['sources'])} sources "
        f"({', '.join(counts['sources'])}); {result.design}"
    )
    if result.demographics is not None and len(result.demographics) > 1:
        details = [f"{row.variable}: {row.summary}" for row in result.demographics.iloc[1:].itertuples()]
        sentences.append("Participants reported " + "; ".join(details))
    sentences.append(_exclusions(result))
    sentences.extend(result.analysis.methods)
    agreement = result.agreement
    if agreement["n_units"]:
        interval = ""
        if agreement["ci_low"] == agreement["ci_low"]:  # not NaN
            interval = (f" [{number(agreement['ci_low'], 2)}, {number(agreement['ci_high'], 2)}], "
                        f"{config.confidence:.0%} percentile interval over {config.bootstrap} "
                        f"bootstrap resamples of units")
        sentences.append(
            f"Agreement between participants was measured with Krippendorff's alpha at the "
            f"{agreement['level']} level over the {agreement['n_units']} units ({agreement['unit']}) "
            f"judged at least twice: alpha = {number(agreement['alpha'], 3)}{interval}"
        )
    for row in result.quality.itertuples():
        sentences.append(f"Attention: {row.check}: {number(row.value, 3)} ({row.detail}, "
                         f"{row.participants} participants)")
    dprime = " (d' has one value per participant)" if "dprime" in result.analysis.tests else ""
    but = ", but for agreement," if agreement["n_units"] else ""
    if getattr(config, "random_clips", True):
        sentences.append(
            f"All intervals are {config.confidence:.0%} and{but} treat participants and clips as "
            f"random samples: a resample of participants keeps all of their judgements{dprime}, "
            f"a resample of clips all of theirs, because one person's judgements are alike, and "
            f"so are the judgements of one clip, and neither are independent observations; "
            f"no p-value counts judgements as independent, and p-values of families of "
            f"comparisons are Holm-corrected"
        )
    else:
        sentences.append(
            f"All intervals are {config.confidence:.0%} and{but} over participants, for these "
            f"clips: a resample of participants keeps all of their judgements{dprime}, because "
            f"one person's judgements are alike and are not independent observations; the clips "
            f"were held fixed, so no verdict reaches other clips of the same sources; p-values "
            f"of families of comparisons are Holm-corrected"
        )
    if counts["participants"] < MIN_PARTICIPANTS:
        sentences.append(f"With {counts['participants']} participants (fewer than "
                         f"{MIN_PARTICIPANTS}) these intervals are rough")
    return " ".join(_sentence(s) for s in sentences if s)


def _exclusions(result) -> str:
    table = result.exclusions.set_index("rule")
    before = table.iloc[0]
    rules = table.iloc[1:-1]
    applied = rules.loc[rules["applied"] == "yes"]
    parts = [f"{row.Index.lower()}: {row.participants} participants, {row.trials} trials, "
             f"{row.judgements} judgements" for row in applied.itertuples()]
    text = ""
    if parts:
        text = (f"Of {before['judgements']} main-trial judgements from {before['participants']} "
                f"participants we excluded those of participants and trials that met a rule ("
                + "; ".join(parts) + ")")
    elif not result.config.exclusions:
        flagged = [f"{row.Index.lower()}: {row.judgements} judgements" for row in rules.itertuples()
                   if row.applied.startswith("no")]
        text = "No exclusions were applied" + (f" (the rules would have flagged {'; '.join(flagged)})"
                                               if flagged else "")
    else:
        text = "No judgement met an exclusion rule"
    counted = rules.loc[rules["applied"].str.startswith("no (counted only")
                        & (rules["participants"] > 0)]
    if result.config.exclusions and len(counted):
        text += "; " + "; ".join(
            f"{row.participants} participants {row.Index[0].lower() + row.Index[1:]} (reported, "
            f"not excluded)" for row in counted.itertuples())
    skipped = rules.loc[rules["applied"].str.startswith("skipped")]
    if len(skipped):
        text += ("; the rule on answering faster than the clip length could not be applied because "
                 "the table has no clip durations or answer times")
    text += "; catch trials and repeated trials do not enter the statistics"
    return text


def _sentence(text: str) -> str:
    text = text.strip()
    text = text[0].upper() + text[1:]
    return text if text.endswith(".") else text + "."
