"""Experiments layer: datasets, perturbations, evaluation and reports.

The core library never imports this package.
"""
