"""The methods paragraph of a report: participants, design, exclusions, tests, agreement.

Every sentence follows what the study did, never a study type's template alone: the
choices the participants had (the type's options, through its ``describe`` hook), the
checks and repeats the table holds, the outcomes of the people who took part, the
exclusion rules that removed something, the units resampled and the models fitted (the
type's ``methods`` sentences), where each method's clips come from (the caller's
``sources_text``: checkpoints, budgets, seeds and their objective metrics), and the
agreement with one precision for the estimate and its interval. Simulated participants (bots) are named as such, first; their made-up
demographics are never summarised.
"""

from __future__ import annotations

from analysis.agreement import MIN_AGREEMENT_UNITS
from analysis.formatting import contains, number, plural, word_list
from analysis.stats import MIN_PARTICIPANTS

# Decimals of Krippendorff's alpha and of its interval (one precision for both).
ALPHA_DIGITS = 2

# How each participant outcome of the export reads: (one, several), in this order.
OUTCOMES = {
    "completed": ("completed the study", "completed the study"),
    "failed_attention": ("was stopped after failing the attention checks",
                         "were stopped after failing the attention checks"),
    "screened_out": ("was screened out", "were screened out"),
    "no_consent": ("did not consent", "did not consent"),
    "timed_out": ("timed out", "timed out"),
    "": ("had not finished when the data were exported",
         "had not finished when the data were exported"),
}


def simulated_banner(result) -> str:
    """Return the warning that some or all analysed participants were simulated (bots),
    or ``""``: the report's header and the paragraph's first sentence."""
    n, total = result.counts.get("simulated", 0), result.counts["participants"]
    if not n:
        return ""
    if n == total:
        return (f"These data are simulated: all {plural(total, 'analysed participant')} "
                f"{'was a bot' if total == 1 else 'were bots'} (simulated participants), not "
                f"people, so nothing here describes human judgement")
    return (f"{n} of the {total} analysed participants {'was a bot' if n == 1 else 'were bots'} "
            f"(simulated participants) whose answers are in these results")


def methods_paragraph(result) -> str:
    """Return a paragraph describing how ``result`` (a ``StudyResult``) was obtained."""
    sentences = [simulated_banner(result)]
    sentences += _participants(result)
    sentences += _design(result)
    sentences += list(getattr(result, "sources_text", None) or [])
    sentences += _exclusions(result)
    sentences.extend(result.analysis.methods)
    sentences += _attention(result)
    sentences += _agreement(result)
    sentences.append(_inference(result))
    counts = result.counts
    if counts["participants"] < MIN_PARTICIPANTS:
        sentences.append(f"With {plural(counts['participants'], 'participant')} (fewer than "
                         f"{MIN_PARTICIPANTS}) these intervals are rough")
    return " ".join(_sentence(s) for s in sentences if s)


def _participants(result) -> list[str]:
    counts = result.counts
    sentences = []
    outcomes = counts.get("outcomes") or {}
    ended = {k: v for k, v in (outcomes.get("by_outcome") or {}).items() if v}
    if ended:
        parts = []
        order = list(OUTCOMES)
        for key in sorted(ended, key=lambda k: (order.index(k) if k in order else len(order), k)):
            one, several = OUTCOMES.get(key, (f"ended as {key.replace('_', ' ')}",) * 2)
            parts.append(f"{ended[key]} {one if ended[key] == 1 else several}")
        total = outcomes["total"]
        sentences.append(f"Of the {plural(total, 'participant')} who opened the study, "
                         + word_list(parts))
    where = ""
    if counts.get("prompts", 0) > 1:
        where = f" of {counts['prompts']} text prompts"
    elif counts["actions"] > 1:
        where = f" of {counts['actions']} actions"
    sources = counts["sources"]
    sentences.append(
        f"We analysed {plural(counts['judgements'], 'judgement')} from "
        f"{plural(counts['participants'], 'participant')} in {plural(counts['trials'], 'trial')}"
        f"{where}, comparing {len(sources)} sources ({word_list(sources)})")
    demographics = result.demographics
    if demographics is not None and len(demographics) > 1:
        rows = [row for row in demographics.iloc[1:].itertuples()
                if not row.variable.startswith("simulated")]
        people = counts["participants"] - counts.get("simulated", 0)
        if rows and people > 0:
            details = [f"{_variable(row.variable)} ({row.summary})" for row in rows]
            sentences.append("The participants who were people reported their "
                             if counts.get("simulated") else "Participants reported their ")
            sentences[-1] += word_list(details)
    return sentences


def _variable(name: str) -> str:
    return name.removesuffix("_range").replace("_", " ")


def _design(result) -> list[str]:
    counts, options = result.counts, result.config.study_options or {}
    design = result.design
    if result.criterion:
        design += f"; this analysis is of the question '{result.criterion}'"
    sentences = [design[0].upper() + design[1:]]
    checks = []
    catch = _per_participant(counts, "catch", options.get("catch_trials"))
    instructed = _per_participant(counts, "instructed", options.get("instructed_checks"))
    repeats = _per_participant(counts, "repeat", options.get("repeat_trials"))
    if catch:
        checks.append(catch.format(what="catch trial", what_many="catch trials")
                      + " (a visibly broken clip to spot)")
    if instructed:
        checks.append(instructed.format(what="instructed check", what_many="instructed checks")
                      + " (the trial's text said which answer to give)")
    if checks:
        sentences.append("Attention was checked with " + word_list(checks))
    if repeats:
        sentences.append("Showing " + repeats.format(what="main trial", what_many="main trials")
                         + " a second time measured how consistently participants answered")
    if options.get("practice"):
        sentences.append("A practice trial came first; its answer is not analysed")
    sentences += adaptive_sentences(options)
    return sentences


def _target_text(target) -> str:
    if isinstance(target, dict) and "versus" in target:
        return f"each difference between {target['versus']} and another source"
    if target == "top_two":
        return "the difference between the two sources estimated best"
    return "every difference between neighbours in the estimated order of the sources"


def adaptive_sentences(options: dict) -> list[str]:
    """Return how the study chose its trials and how it stopped, from its ``design``,
    ``adaptive``, ``stop_when`` and ``stopped`` settings (``Study`` fields; none for a
    balanced study without a stopping rule or a table analysed without its study)."""
    sentences = []
    settings = options.get("adaptive") or {}
    target = settings.get("target", "order")
    if options.get("design") == "adaptive":
        every = settings.get("every", 50)
        floor = settings.get("floor", 0.2)
        minimum = settings.get("min_showings", 2)
        sentences.append(
            f"The design was adaptive: after every clip had been shown {plural(minimum, 'time')}, "
            f"the sources shown together in a main trial were drawn from a distribution "
            f"recomputed in the background every {plural(every, 'answered main trial')}, "
            f"favouring the sources whose answers were expected to narrow most the intervals "
            f"of {_target_text(target)}, with {floor:.0%} of it spread evenly over every choice "
            f"of sources; clips "
            f"were taken least-shown first, positions balanced within each participant, and "
            f"no participant saw the same clips together twice")
        if (settings.get("batch") or 0) > 1:
            sentences.append(
                f"The pairs of sources were planned in batches of {settings['batch']} "
                f"comparisons, each pair chosen after the posterior had been updated by the "
                f"pairs chosen before it in the batch")
        sentences.append(
            "Which sources were shown together depended only on answers already given, so the "
            "likelihood of the answers, and the fit, are those of a fixed design; the "
            "intervals resample participants and clips as for a balanced design")
    stopped, rule = options.get("stopped") or {}, options.get("stop_when") or {}
    if stopped:
        n = plural(stopped["judgements"], "answered main trial")
        what = _target_text(stopped.get("target", target))
        if stopped["rule"] == "interval_width":
            how = (f"when the widest 95% interval of {what} was {stopped['width']:.2f}, at "
                   f"most the rule's {stopped['value']:g} (logit scale), after {n}")
            if stopped.get("interval") == "clips":
                how += (" (the rule's own interval: the model's variance with one clip variance "
                        "pooled over every pair of sources, computed at every check; the "
                        "intervals reported here resample participants and clips and can be "
                        "wider)")
        elif stopped["rule"] == "rank_certainty":
            how = (f"when the posterior probability that the estimated order of {what} was "
                   f"right reached {stopped['certainty']:.2f}, at least the rule's "
                   f"{stopped['value']:g}, after {n}")
        else:
            how = f"when its budget of {plural(stopped['value'], 'answered main trial')} was reached ({n})"
        sentences.append(
            f"The study stopped by its stopping rule {how}; the rule was checked in the "
            f"background every few answers, its places were closed then, and the answers of "
            f"those still taking part were kept")
    elif rule:
        wanted = ", ".join(f"{name.replace('_', ' ')} {value:g}" for name, value in rule.items())
        sentences.append(f"The study had a stopping rule ({wanted}) that had not been met when "
                         f"the data were exported")
    return sentences


def _per_participant(counts, kind: str, planned) -> str:
    """Return how many trials of ``kind`` (catch, instructed, repeat) there were, as a
    template with ``{what}``/``{what_many}``: per participant when the study says so or
    every participant had as many, else in all; ``""`` when there were none."""
    trials, people = counts.get(f"{kind}_trials", 0), counts.get(f"{kind}_participants", 0)
    if not trials:
        return ""
    per = planned or (trials // people if people and trials % people == 0 else None)
    if per:
        return f"{per} {{{'what' if per == 1 else 'what_many'}}} per participant"
    return f"{trials} {{what_many}} in all" if trials != 1 else "1 {what}"


def _exclusions(result) -> list[str]:
    table = result.exclusions.set_index("rule")
    before = table.iloc[0]
    rules = table.iloc[1:-1]
    analysed = table.iloc[-1]
    config = result.config
    applied = rules.loc[(rules["applied"] == "yes") & (rules["judgements"] > 0)]
    sentences = []
    if len(applied):
        parts = [_rule_text(rule, row) for rule, row in applied.iterrows()]
        sentences.append(
            "We excluded " + word_list(parts) + f", leaving {analysed['judgements']} of the "
            f"{plural(before['judgements'], 'main-trial judgement')} from "
            f"{plural(before['participants'], 'participant')}")
    elif not config.exclusions:
        flagged = [_rule_text(rule, row) for rule, row in rules.iterrows()
                   if row["applied"].startswith("no") and row["judgements"] > 0]
        sentences.append("No exclusions were applied" + (
            f"; the rules would have removed {word_list(flagged)}" if flagged else ""))
    elif (rules["applied"] == "yes").any():
        sentences.append("No participant or trial met an exclusion rule")
    counted = rules.loc[rules["applied"].str.startswith("no (counted only")
                        & (rules["participants"] > 0)]
    if config.exclusions and len(counted):
        sentences.append(word_list(
            f"{plural(row['participants'], 'participant')} {_lower(rule)}" for rule, row
            in counted.iterrows()) + " (reported, not excluded)")
    skipped = rules.loc[rules["applied"].str.startswith("skipped")]
    if len(skipped):
        sentences.append(
            word_list(f"the rule '{_lower(rule)}' could not be applied ({_why_skipped(row)})"
                      for rule, row in skipped.iterrows()))
    counts = result.counts
    kept_out = [name for name, n in (("catch trials", counts.get("catch_trials", 0)),
                                     ("instructed checks", counts.get("instructed_trials", 0)),
                                     ("repeated trials", counts.get("repeat_trials", 0))) if n]
    if kept_out:
        sentences.append(word_list(kept_out).capitalize() + " do not enter the statistics")
    return sentences


def _why_skipped(row) -> str:
    why = row["applied"].removeprefix("skipped").strip(" ()")
    if why == "no data":
        return "the table has no clip durations or answer times"
    return why.replace("no ", "the table has no ", 1) if why.startswith("no ") else why


def _rule_text(rule: str, row) -> str:
    """Return what a rule removed: ``2 participants who failed an attention check (24
    judgements)`` or ``5 trials answered before ... (3 participants, 10 judgements)``."""
    what = _lower(rule)
    judgements = plural(row["judgements"], "judgement")
    if row.get("excludes") == "trials":
        what = what.removeprefix("answered ")
        return (f"{plural(row['trials'], 'trial')} answered {what} "
                f"({plural(row['participants'], 'participant')}, {judgements})")
    if what.endswith(")"):  # "... (MUSHRA post-screening)": one pair of brackets
        return f"{plural(row['participants'], 'participant')} who {what[:-1]}; {judgements})"
    return f"{plural(row['participants'], 'participant')} who {what} ({judgements})"


def _lower(text: str) -> str:
    return text[:1].lower() + text[1:]


def _attention(result) -> list[str]:
    sentences = []
    for row in result.quality.itertuples():
        if row.check.startswith("catch"):
            counts = result.counts
            kinds = [name for name, key in (("catch trials", "catch_trials"),
                                            ("instructed checks", "instructed_trials"))
                     if counts.get(key)]
            what = kinds[0] if len(kinds) == 1 else "attention checks"
            passed = int(round(row.value * row.n))
            if row.n == 1:
                what, were = what[:-1], "was"
            else:
                were = "were"
            sentences.append(f"{passed} of {row.n} {what} {were} passed "
                             f"({number(100 * row.value, 0)} %, "
                             f"{plural(row.participants, 'participant')})")
        elif row.check.startswith("repeated"):
            detail = row.detail.split("; ", 1)
            extra = f"; {detail[1]}" if len(detail) > 1 else ""
            sentences.append(f"{number(100 * row.value, 0)} % of "
                             f"{plural(row.n, 'repeated judgement')} "
                             f"({plural(row.participants, 'participant')}) matched the first "
                             f"answer{extra}")
        else:
            sentences.append(f"{row.check}: {number(row.value, 3)} ({row.detail})")
    return sentences


def alpha_text(agreement) -> str:
    """Return alpha and its interval with one precision (:data:`ALPHA_DIGITS`), or alpha
    alone with why, when the interval does not contain it."""
    alpha, low, high = agreement["alpha"], agreement["ci_low"], agreement["ci_high"]
    shown = number(alpha, ALPHA_DIGITS)
    if low != low or high != high:  # NaN: no bootstrap
        return f"alpha = {shown}"
    if not contains(alpha, low, high):
        return (f"alpha = {shown} (its bootstrap percentile interval, "
                f"[{number(low, ALPHA_DIGITS)}, {number(high, ALPHA_DIGITS)}], does not contain "
                f"it: too few units vary between resamples for a usable interval)")
    return f"alpha = {shown} [{number(low, ALPHA_DIGITS)}, {number(high, ALPHA_DIGITS)}]"


def _agreement(result) -> list[str]:
    agreement, config = result.agreement, result.config
    n = agreement["n_units"]
    if not n:
        return []
    unit, many = (("pair of clips", "pairs of clips") if agreement.get("unit") == "pair of stimuli"
                  else ("clip", "clips"))
    units = plural(n, unit, many)
    interval = ""
    if agreement["ci_low"] == agreement["ci_low"] and contains(
            agreement["alpha"], agreement["ci_low"], agreement["ci_high"]):
        interval = (f" ({config.confidence:.0%} percentile interval over {config.bootstrap} "
                    f"bootstrap resamples of the {many})")
    sentences = [
        f"Agreement between participants was measured with Krippendorff's alpha "
        f"({agreement['level']} level) over the {units} that two or more participants judged: "
        f"{alpha_text(agreement)}{interval}"]
    if n < MIN_AGREEMENT_UNITS:
        sentences.append(
            f"With fewer than {MIN_AGREEMENT_UNITS} {many} judged more than once, this alpha "
            f"is a rough indication only: a bootstrap over so few units is coarse, and a "
            f"single {unit} moves alpha by tenths")
    return sentences


def _inference(result) -> str:
    config = result.config
    dprime = " (d' has one value per participant)" if "dprime" in result.analysis.tests else ""
    ci = f"{config.confidence:.0%}"
    if config.bootstrap <= 0:
        return ("No intervals were computed (the bootstrap was switched off); p-values of "
                "families of comparisons are Holm-corrected")
    if getattr(config, "random_clips", True):
        return (f"Intervals are {ci}; apart from agreement they treat both participants and "
                f"clips as random samples, since one person's judgements are alike and so are "
                f"the judgements of one clip: a resample keeps all of a participant's "
                f"judgements{dprime}, or all of a clip's, and no p-value counts judgements as "
                f"independent; p-values of families of comparisons are Holm-corrected")
    return (f"Intervals are {ci}; apart from agreement they are over participants only, a "
            f"resample keeping all of a participant's judgements{dprime}: the clips were held "
            f"fixed, so no verdict reaches other clips of the same sources; "
            f"p-values of families of comparisons are Holm-corrected")


def _sentence(text: str) -> str:
    text = text.strip()
    text = text[0].upper() + text[1:]
    return text if text.endswith(".") else text + "."
