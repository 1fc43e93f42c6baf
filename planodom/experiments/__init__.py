"""Experiments that regenerate published results; library calls behind ``planodom experiment``.

- :mod:`planodom.experiments.paper`: the paper's section VI (:func:`run_paper_experiment`).
"""
