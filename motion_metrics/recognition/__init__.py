"""The action classifier behind FID, accuracy, diversity and multimodality (seed 000).

:mod:`~motion_metrics.recognition.classifier` trains and applies it,
:mod:`~motion_metrics.recognition.networks` holds its config and network,
:mod:`~motion_metrics.recognition.augment` its training augmentation and
:mod:`~motion_metrics.recognition.split` which clips it (and the metrics) hold out.
"""

from motion_metrics.recognition.classifier import (
    CHECKPOINT_FORMAT,
    EVAL_EVERY,
    INFERENCE_BATCH,
    KIND,
    PATIENCE,
    ActionClassifier,
    one_thread,
    train_classifier,
)
from motion_metrics.recognition.errors import ClassifierError
from motion_metrics.recognition.networks import FEATURES, ClassifierConfig, GRURecogniser
from motion_metrics.recognition.split import (
    TEST_FRACTION,
    VALIDATION_FRACTION,
    Split,
    make_split,
    validation_split,
)

__all__ = [
    "CHECKPOINT_FORMAT", "EVAL_EVERY", "FEATURES", "INFERENCE_BATCH", "KIND", "PATIENCE",
    "TEST_FRACTION", "VALIDATION_FRACTION", "ActionClassifier", "ClassifierConfig",
    "ClassifierError", "GRURecogniser", "Split", "make_split", "one_thread", "train_classifier",
    "validation_split",
]
