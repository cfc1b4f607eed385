"""Commands that never touch the database: datasets, training, sampling, rendering,
imports, objective metrics and method comparisons (``datasets``, ``train``, ``sample``,
``render``, ``import_motions``, ``evaluate``, ``compare_methods``, ``train_classifier``)."""
