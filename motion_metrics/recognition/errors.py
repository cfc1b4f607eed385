"""The error of the action classifier and its data split."""


class ClassifierError(ValueError):
    """The classifier cannot use its input (other skeleton, length, actions) or its checkpoint is bad."""
