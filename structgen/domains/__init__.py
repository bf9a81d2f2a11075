"""Domains bind a generator to a judge so the evolution engine can optimise it.

Each domain is an ``evolution.Problem``. They are registered by name in :mod:`structgen.experiment`, which turns the
``[problem]`` table of a run configuration into one.
"""
