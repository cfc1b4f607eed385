"""Objective metrics of generated motion, and the protocols that measure methods with them.

Plain Python (numpy, torch); never imports Django, nor :mod:`analysis` (the statistics of
study responses). Modules, from the arrays up:

- :mod:`motion_metrics.metrics`: FID, accuracy, diversity, multimodality, MMD_avg,
  MMD_seq, APD, n-APD, mode homogeneity, dist_e, on numpy arrays;
- :mod:`motion_metrics.protocol`: the repeats and 95 % intervals (Action2Motion's
  protocol), with the Real column, on numpy arrays;
- :mod:`motion_metrics.evaluate`: motions against a dataset's real clips and an action
  classifier (what ``manage.py evaluate`` runs);
- :mod:`motion_metrics.comparison`, :mod:`motion_metrics.comparison_report`,
  :mod:`motion_metrics.paper_numbers`: every method trained within a budget, evaluated,
  and written up beside the seeds' published numbers (``manage.py compare_methods``).

- :mod:`motion_metrics.recognition`: the GRU action classifier whose features FID and
  accuracy use (``manage.py train_classifier``).

"Comparison" here is of methods' quality; ``benchmarks/`` at the project's root measures
speed. It builds on :mod:`motion` (data, datasets) and :mod:`generation` (methods);
neither imports it.
"""
