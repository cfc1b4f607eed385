"""The objective metrics of one trained model on its dataset: what a study build records per checkpoint.

``compare_methods`` and a study build measure a model the same way: ``n`` motions per
action sampled with one seed (:func:`sample_for_metrics`), evaluated by
:func:`motion_metrics.evaluate.evaluate` (the ``bootstrap`` protocol) against the real
clips the split holds out. A build's numbers for a checkpoint trained as the benchmark
trains it, with the benchmark's classifier, ``n``, repeats and seed, are the benchmark's.
Without a classifier the feature metrics (FID, accuracy, diversity, multimodality) are
listed as not measured; MMD, APD and n-APD need none.
"""

from __future__ import annotations

from typing import Sequence

from motion_metrics.evaluate import EvaluationError, evaluate

METRICS = ("fid", "accuracy", "diversity", "multimodality", "mmd_avg", "mmd_seq", "apd", "n_apd")
CLASSIFIER_METRICS = ("fid", "accuracy", "diversity", "multimodality")


def sample_for_metrics(model, actions: Sequence[str], n: int, seed: int) -> list:
    """Return ``n`` motions per action of ``model``, action by action, drawn with ``seed``."""
    return model.sample([action for action in actions for _ in range(n)], seed=seed)


def measure(model, dataset, classifier=None, *, n: int = 50, repeats: int = 5, seed: int = 0,
            mmd_protocol: str = "heldout", split=None, metrics: Sequence[str] = METRICS) -> dict:
    """Return the metrics of ``model``'s motions against ``dataset``'s held-out clips.

    ``split`` holds out real clips when ``classifier`` (whose own split wins) is absent.
    Returns ``{"metrics": {name: {"mean", "ci", "real": {"mean", "ci"} | None}}, "skipped":
    {name: reason}, "n", "repeats", "seed", "mmd_protocol", "held_out", "classifier"}``.
    """
    known = set(dataset.actions())
    actions = [a for a in model.actions if a in known
               and (classifier is None or a in classifier.actions)]
    if not actions:
        raise EvaluationError(f"{model.name} knows no action of dataset {dataset.name!r}"
                              + ("" if classifier is None else " that the classifier knows"))
    skipped = {}
    wanted = []
    for name in metrics:
        if classifier is None and name in CLASSIFIER_METRICS:
            skipped[name] = "needs an action classifier"
        else:
            wanted.append(name)
    motions = sample_for_metrics(model, actions, n, seed)
    values = evaluate(dataset, motions, classifier, wanted, repeats, seed,
                      mmd_protocol=mmd_protocol, split=split)
    skipped.update(values.get("skipped", {}))
    return {
        "metrics": {name: {"mean": row["mean"], "ci": row["ci"],
                           "real": None if not row.get("real") else
                           {"mean": row["real"]["mean"], "ci": row["real"]["ci"]}}
                    for name, row in values["metrics"].items()},
        "skipped": skipped,
        "n": int(n), "repeats": int(repeats), "seed": int(seed),
        "mmd_protocol": values["mmd_protocol"]["name"],
        "held_out": values["real"]["split"], "n_held_out": values["real"]["n_test"],
        "classifier": values["classifier"],
    }
