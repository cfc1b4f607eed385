"""The blindness audit: can a script tell clips apart by what it is sent?

Two questions are asked of a study's clips: can the source of a judged clip be told
(real against generated; without real clips, the first source by name against the
others), and can a catch clip be told from the judged clips? Each is asked of each family
of features (:mod:`analysis.clip_features`) by :func:`leak_test`: a ridge classifier on the
family's features (and their squares, which catch outliers on either side), scored by
leave-one-out, and each feature alone; the statistic is the larger of the classifier's
AUC and the best single feature's (either way round), and its p-value is that of a
permutation test (the labels shuffled ``PERMUTATIONS`` times, the same statistic each
time), valid for any number of clips. The audit also says which AUC it could have told
from luck (the permutations' ``1 - alpha`` quantile): with few clips only a large leak
can show, and it says so in words.

What a leak is depends on the family and the question (:func:`assess`):

- ``delivery`` (sizes, headers, boxes, frame-size tables, padding layout) must tell
  nothing about either: a significant result fails the study.
- ``bitstream`` and ``payload`` are content: a script that parses the H.264 stream for
  its true frame sizes, or reads the player's joints, reads the motion itself, which is
  what participants judge. For the source question they are reported as content ("a
  script that parses the bitstream tells real from generated with AUC 0.99, as a viewer
  of the motion could") and never fail; for the catch question they must be at chance,
  since a script that picks out catch clips passes attention checks without watching.
- ``hashes``: with several deliveries per clip, no two deliveries may share a file hash or
  an ETag (a repeat's clip matching its first showing, a catch clip matching another
  participant's); sharing fails. Two deliveries of one clip always show the same clip
  (the content keys match), which is what a repeat is; that is reported, not failed.

The tests that can fail share the error rate ``ALPHA`` (Bonferroni), so an honest study
fails one by chance at most once in a hundred audits. A deep audit asks each question of
two deliveries of every clip and counts the larger p-value (an intersection-union test):
what is laid out anew for every delivery (the split of filler and padding) is independent
between the two, so a chance result of one delivery's draws fails only when the other's
repeats it (about ``ALPHA`` squared), while a real leak, which follows the clip, shows in
both.

Plain Python and NumPy: the Django side (``studyapp.results.audit``) fetches the clips.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import rankdata

from analysis.clip_features import content_keys, features, file_hashes, same_content

ALPHA = 0.01
PERMUTATIONS = 2000
REPLICATES = 2  # deliveries per clip a deep audit's leak must show on
TOO_FEW_AUC = 0.9  # a test that could only see leaks above this AUC has too few clips
RIDGE = (0.1, 1.0, 10.0)  # penalties, times the mean squared feature norm
QUESTIONS = {"source": "real from generated", "catch": "catch clips from judged clips"}
CONTENT = {"bitstream": "parses the H.264 bitstream (true frame sizes) and the poster's "
                        "image data",
           "payload": "reads the in-browser player's joints (bone lengths, speeds, jerk, "
                      "value ranges)"}


@dataclass
class ClipRecord:
    """One stimulus as the audit saw it: its role and source (from the database) and what
    each delivery sent, ``{ext: (headers, bytes)}`` per delivery."""

    role: str
    source: str
    deliveries: list[dict] = field(default_factory=list)
    action: str = ""


def _design(rows: list[dict]) -> tuple[np.ndarray, list[str]]:
    """Return standardised features (constant ones dropped) and their names."""
    names = sorted({name for row in rows for name in row})
    x = np.array([[row.get(name, 0.0) for name in names] for row in rows], dtype=float)
    if not x.size:
        return np.zeros((len(rows), 0)), []
    x[~np.isfinite(x)] = 0.0
    spread = x.std(axis=0)
    keep = spread > 1e-9 * (np.abs(x).max(axis=0) + 1.0)
    x, names = x[:, keep], [n for n, k in zip(names, keep) if k]
    return (x - x.mean(axis=0)) / np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0), names


def _aucs(scores: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Return the AUC of each column of ``scores`` ``(n, P)`` for 0/1 ``labels`` ``(n, P)``."""
    ranks = rankdata(scores, axis=0)
    positives = labels.sum(axis=0)
    negatives = len(labels) - positives
    return ((ranks * labels).sum(axis=0) - positives * (positives + 1) / 2) / (positives * negatives)


def _ridge_aucs(z: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Return the leave-one-out AUC of kernel ridge regressions on ``z`` for each column
    of ``labels`` ``(n, P)``, the best of the penalties :data:`RIDGE`."""
    n = len(z)
    design = np.hstack([z, z * z - (z * z).mean(axis=0)])
    gram = design @ design.T
    centred = labels - labels.mean(axis=0)
    best = np.full(labels.shape[1], -np.inf)
    for scale in RIDGE:
        penalty = scale * max(float(np.trace(gram)) / n, 1e-9)
        hat = gram @ np.linalg.inv(gram + penalty * np.eye(n))
        diagonal = np.clip(np.diag(hat), None, 1 - 1e-9)[:, None]
        loo = (hat @ centred - diagonal * centred) / (1 - diagonal)
        best = np.maximum(best, _aucs(loo, labels))
    return best


def leak_test(rows: list[dict], labels, alpha: float = ALPHA,
              permutations: int = PERMUTATIONS, seed: int = 0) -> dict:
    """Return how well the features ``rows`` tell the ``labels`` (booleans) apart; see the
    module docstring. Keys: ``n``, ``positives``, ``auc`` (the statistic), ``p_value``,
    ``detectable_auc``, ``too_few``, ``significant``, ``best_feature``, ``best_auc``
    (that feature alone, 0.5 to 1), ``model_auc``, ``accuracy`` and ``chance``.
    Fewer than two clips of either label: nothing to tell apart (``auc`` None).
    """
    y = np.asarray(labels, dtype=float)
    n, positives = len(y), int(y.sum())
    chance = max(positives, n - positives) / n if n else 1.0
    out = {"n": n, "positives": positives, "chance": chance, "alpha": alpha, "auc": None,
           "p_value": 1.0, "detectable_auc": None, "too_few": True, "significant": False,
           "best_feature": "", "best_auc": None, "model_auc": None, "accuracy": None}
    if min(positives, n - positives) < 2:
        return out
    z, names = _design(rows)
    rng = np.random.default_rng(seed)
    shuffled = np.stack([y] + [rng.permutation(y) for _ in range(permutations)], axis=1)
    if names:
        model = _ridge_aucs(z, shuffled)
        ranks = rankdata(z, axis=0)  # (n, features)
        per = (shuffled.T @ ranks - positives * (positives + 1) / 2) / (positives * (n - positives))
        strength = np.maximum(per, 1 - per)  # (P + 1, features), either way round
        statistic = np.maximum(model, strength.max(axis=1))
        best = int(np.argmax(strength[0]))
        out.update(best_feature=names[best], best_auc=float(strength[0, best]),
                   model_auc=float(model[0]))
    else:
        statistic = np.full(permutations + 1, 0.5)
    null = statistic[1:]
    out["auc"] = float(statistic[0])
    out["p_value"] = float((1 + (null >= statistic[0] - 1e-12).sum()) / (permutations + 1))
    out["detectable_auc"] = float(np.quantile(null, 1 - alpha))
    out["too_few"] = out["detectable_auc"] >= TOO_FEW_AUC
    out["significant"] = out["p_value"] < alpha
    if names:
        # Leave-one-out guesses of the best-scoring feature's threshold rule, for a reader
        # who thinks in accuracy: the share right against always guessing the larger class.
        column = z[:, best] * (1 if per[0, best] >= 0.5 else -1)
        out["accuracy"] = _loo_threshold_accuracy(column, y > 0.5)
    return out


def _loo_threshold_accuracy(values: np.ndarray, labels: np.ndarray) -> float:
    """Return the leave-one-out accuracy of the best threshold on one feature (higher
    values guessed positive), the threshold chosen without the clip it guesses."""
    right = 0
    for i in range(len(values)):
        keep = np.arange(len(values)) != i
        v, t = values[keep], labels[keep]
        cuts = np.unique(v)
        scores = [((v >= c) == t).mean() for c in cuts] + [(~t).mean()]
        k = int(np.argmax(scores))
        guess = bool(values[i] >= cuts[k]) if k < len(cuts) else False
        right += guess == labels[i]
    return right / len(values)


def _could_show(result: dict) -> str:
    detectable = result["detectable_auc"]
    words = (f"{result['n']} clips ({result['positives']} against "
             f"{result['n'] - result['positives']}) could show a leak of AUC {detectable:.2f} "
             f"or more")
    if result["too_few"]:
        words += "; too few clips to tell a smaller one, so this part vouches for little"
    return words


def verdict(question: str, family: str, result: dict) -> dict:
    """Return the audit's entry for one question and family: the test's numbers with
    ``kind`` (``delivery`` or ``content``), ``passed`` and ``says`` (see the module
    docstring for the rule)."""
    what = QUESTIONS[question]
    kind = "delivery" if family == "delivery" else "content"
    entry = {"question": question, "family": family, "kind": kind, **result}
    if result["auc"] is None:
        entry.update(passed=True, says=f"nothing to tell apart: fewer than two clips of a kind "
                                       f"({result['n']} clips, {result['positives']} of one)")
        return entry
    numbers = f"AUC {result['auc']:.2f}, p = {result['p_value']:.2g}"
    if result.get("deliveries_tested", 1) > 1:
        numbers += f" (the larger of {result['deliveries_tested']} deliveries' p)"
    if result["best_feature"]:
        numbers += f"; best single feature {result['best_feature']} ({result['best_auc']:.2f})"
    reader = ("what a browser receives (sizes, headers, boxes, frame-size tables, padding)"
              if kind == "delivery" else f"a script that {CONTENT[family]}")
    if kind == "content" and question == "source":
        told = "tells" if result["significant"] else "does not tell"
        entry.update(passed=True, says=(
            f"content: {reader} {told} {what} ({numbers}), as a viewer of the motion could; "
            f"not a blindness failure"))
    elif result["significant"]:
        harm = ("it can pass attention checks without watching" if question == "catch" else
                "participants' browsers can tell the source")
        entry.update(passed=False, says=f"FAILED: {reader} tells {what} ({numbers}): {harm}")
    else:
        entry.update(passed=True, says=f"passed: {reader} does not tell {what} ({numbers}); "
                                       f"{_could_show(result)}")
    return entry


def _labels(clips: list[ClipRecord]) -> dict[str, tuple[list[int], list[bool]]]:
    """Return per question the clips it asks about and their labels."""
    judged = [i for i, c in enumerate(clips) if c.role == "judged"]
    shown = [i for i, c in enumerate(clips) if c.role in ("judged", "catch")]
    sources = sorted({clips[i].source for i in judged})
    told = "real" if "real" in sources or not sources else sources[0]
    return {"source": (judged, [clips[i].source == told for i in judged]),
            "catch": (shown, [clips[i].role == "catch" for i in shown])}


def delivery_check(clips: list[ClipRecord]) -> dict:
    """Return the ``hashes`` entry: whether any two deliveries share a file's sha256 or an
    ETag (a failure: see the module docstring)."""
    hashes: Counter = Counter()
    etags: Counter = Counter()
    deliveries = 0
    for clip in clips:
        for files in clip.deliveries:
            deliveries += 1
            for ext, digest in file_hashes(files).items():
                hashes[(ext, digest)] += 1
            for ext, (headers, _) in files.items():
                tag = {k.lower(): v for k, v in headers.items()}.get("etag")
                if tag:
                    etags[tag] += 1
    repeated = Counter()
    for (ext, _), n in hashes.items():
        if n > 1:
            repeated[ext] += n - 1
    repeated_tags = sum(n - 1 for n in etags.values() if n > 1)
    several = sum(len(c.deliveries) > 1 for c in clips)
    passed = not repeated and not repeated_tags
    if passed:
        says = (f"passed: {deliveries} deliveries of {len(clips)} clips ({several} of them "
                f"delivered more than once), no two with the same bytes or ETag: hashing what "
                f"is sent matches no repeat and no other participant's catch clip")
    else:
        which = ", ".join(f"{n} {ext}" for ext, n in sorted(repeated.items())) or "none"
        says = (f"FAILED: deliveries repeat bytes ({which}) or ETags ({repeated_tags}): a "
                f"script that hashes them recognises a repeated trial's clip and a catch clip "
                f"seen before; build the clips with build_stimuli (padded files) and serve "
                f"them through this app, which gives every delivery bytes of its own")
    return {"question": "deliveries", "family": "hashes", "kind": "delivery", "passed": passed,
            "says": says, "n": deliveries, "clips": len(clips),
            "repeated_bytes": sum(repeated.values()), "repeated_etags": repeated_tags}


def content_check(clips: list[ClipRecord]) -> dict:
    """Return the ``content`` entry: how often two deliveries of one clip show the same
    clip to a script that strips what readers skip (by design: a repeat is the same clip),
    how often two clips do, and how many catch clips there are to share."""
    keys = [[content_keys(files) for files in clip.deliveries] for clip in clips]
    same, pairs, confused = Counter(), Counter(), Counter()
    for mine in keys:
        for a in range(len(mine)):
            for b in range(a + 1, len(mine)):
                for ext in mine[a]:
                    pairs[ext] += 1
                    same[ext] += same_content(ext, mine[a][ext], mine[b][ext])
    firsts = [mine[0] for mine in keys if mine]
    for a in range(len(firsts)):
        for b in range(a + 1, len(firsts)):
            for ext in firsts[a]:
                confused[ext] += ext in firsts[b] and same_content(ext, firsts[a][ext],
                                                                  firsts[b][ext])
    catch = sum(c.role == "catch" for c in clips)
    actions = len({c.action for c in clips if c.role == "catch"}) or 1
    shares = ", ".join(f"{ext} {same[ext]}/{pairs[ext]}" for ext in sorted(pairs)) or "none"
    says = (f"content: two deliveries of one clip show the same clip to a script that strips "
            f"filler and padding ({shares} pairs), as a viewer recognises a repeated clip; two "
            f"different clips never do ({sum(confused.values())} alike). {catch} catch clips "
            f"(about {catch / actions:.0f} per action) are handed out least used first, so "
            f"participants share one only once each has been shown")
    return {"question": "deliveries", "family": "content", "kind": "content", "passed": True,
            "says": says, "n": sum(pairs.values()), "same_clip_alike": sum(same.values()),
            "different_clips_alike": sum(confused.values()), "catch_clips": catch}


def assess(clips: list[ClipRecord], deep: bool = True, seed: int = 0,
           permutations: int = PERMUTATIONS) -> dict[str, dict]:
    """Return the audit of ``clips``: ``{"<question>: <family>": entry}`` (see
    :func:`verdict`), and with ``deep`` the content families and the deliveries' hashes.
    Basic: the delivery family of each clip's first delivery only."""
    # Deep: each test on two deliveries of every clip, the larger p counting (see the
    # module docstring); basic: the first delivery.
    rounds = REPLICATES if deep and all(len(c.deliveries) >= REPLICATES for c in clips) else 1
    rows = [[features(clip.deliveries[k]) for clip in clips] for k in range(rounds)]
    families = ["delivery"] + (["bitstream", "payload"] if deep else [])
    families = [f for f in families if any(row[f] for row in rows[0])]
    tests = [(q, f) for q in QUESTIONS for f in families
             if f == "delivery" or q == "catch"]  # the tests that can fail
    alpha = ALPHA / max(1, len(tests) + bool(deep))
    out = {}
    for question, (chosen, labels) in _labels(clips).items():
        for family in families:
            results = [leak_test([batch[i][family] for i in chosen], labels, alpha=alpha,
                                 permutations=permutations, seed=seed) for batch in rows]
            result = max(results, key=lambda r: r["p_value"])
            result["deliveries_tested"] = rounds
            out[f"{question}: {family}"] = verdict(question, family, result)
    if deep:
        out["deliveries: hashes"] = delivery_check(clips)
        out["deliveries: content"] = content_check(clips)
    return out


def passed(result: dict) -> bool:
    """Return whether every entry of an audit passed."""
    return all(part["passed"] for part in result.values())
