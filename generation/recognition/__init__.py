"""The action classifier behind FID, accuracy, diversity and multimodality (seed 000).

:mod:`~generation.recognition.classifier` trains and applies it,
:mod:`~generation.recognition.networks` holds its config and network,
:mod:`~generation.recognition.augment` its training augmentation and
:mod:`~generation.recognition.split` which clips it (and the metrics) hold out.
"""

from generation.recognition.classifier import (
    CHECKPOINT_FORMAT,
    EVAL_EVERY,
    INFERENCE_BATCH,
    KIND,
    PATIENCE,
    ActionClassifier,
    one_thread,
    train_classifier,
)
from generation.recognition.errors import ClassifierError
from generation.recognition.networks import FEATURES, ClassifierConfig, GRURecogniser
from generation.recognition.split import (
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
