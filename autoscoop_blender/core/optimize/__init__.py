"""Optimizers: strategies that place sensors on a ``Problem`` (see ``base.py``)."""
