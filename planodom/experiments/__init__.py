"""Experiments that regenerate published results; library calls behind ``planodom experiment``.

- :mod:`planodom.experiments.paper`: the paper's section VI (:func:`run_paper_experiment`).
- :mod:`planodom.experiments.smoothing`: odometry vs fixed-lag and batch smoothing
  (:func:`run_smoothing_experiment`).
- :mod:`planodom.experiments.consistency`: NEES of relative poses, planes and smoothed
  poses against the truth (:func:`run_consistency_experiment`).
"""
