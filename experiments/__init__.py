"""Tuning studies, each beside its JSON results. Run from the repository root: ``python -m experiments.NAME``
(see docs/experiments/)."""
