"""The next experiment: the record the bench can make that would separate the leading candidates best
(:func:`~diagnosis.design.discriminate.next_experiment`), from the designs on offer
(:mod:`diagnosis.design.space`)."""
from .discriminate import NextExperiment, next_experiment

__all__ = ["NextExperiment", "next_experiment"]
