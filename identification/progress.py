"""What an identification reports while it runs (:class:`Progress`, given to ``identify``'s ``on_progress``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Progress"]


@dataclass(frozen=True)
class Progress:
    """What :func:`identify` reports to ``on_progress`` during the search.

    ``stage`` is ``"generation"`` (after every GA generation: ``X``, ``F`` the
    current non-dominated set, ``knee`` its knee) or ``"polish"`` (after every
    polished point: ``X``, ``F`` of that one point, ``knee = 0``).
    ``n_evaluations`` counts the search's model evaluations so far (GA plus
    polish).
    """

    stage: str
    step: int
    n_evaluations: int
    X: np.ndarray
    F: np.ndarray
    knee: int
