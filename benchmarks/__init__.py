"""Benchmarks and dataset evaluations, run by hand (``python benchmarks/<name>.py``); tests import
their measuring functions as ``benchmarks.<name>`` to assert the figures on ../shared data."""
