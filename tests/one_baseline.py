"""One baseline search for ``identify`` and ``diagnose`` (issue 71): the diagnosis' baseline is never worse than
what ``identify`` finds on the same records.

Read by the families' diagnosis tests (``tests/test_diagnosis_broadband.py``: the broadband family with nothing
withheld and the hint family's effects a baseline takes up in another beam; ``tests/test_diagnosis_blind.py``:
the blind family's withheld effects).  Both parameter sets are weighed in the diagnosis' own terms — its problem
as solved (fit windows, numerics, noise model, priors, the force's sign as taken): ``identify`` fits the whole
record, the diagnosis only its fit windows, so in the diagnosis' terms identify's point is at best as good as a
fit there from the same basin.  A different basin costs many units of χ²; a fit from the same one stops once its
step is resolved against the uncertainty, far below one unit (:data:`SAME_BASIN`).

Measured: the broadband family's four records without an effect and the hint family's six effects taken up in
another beam — the reported baseline no worse (on the broadband ones 0.02–18 % of χ² below identify's
point).  The blind family's ten withheld effects: the search starts from the basin of the config's start (from the
records' better, compensating one a spring at the right end was named a soft segment), and on three of them the
records' own start fits better without an effect — χ² 30,098 against identify's 30,668 (a spring at the right
end), 24,856 against 25,922 (an actuator's lag), 855,253 against 1.05e6 (a point mass), on 8,400 residuals — where
the config start's basin, reported before, had 504,807, 259,641 and 1.10e6.  The baseline reported is now the best
fit without an effect and every refit is weighed against it (``diagnosis.search.rebase``); every family asserts
the baseline reported.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from identification.run import identify

__all__ = ["SAME_BASIN", "assert_no_worse_than_identify"]

#: χ² the diagnosis' baseline may exceed identify's point by in the diagnosis' terms (module docstring): one unit.
SAME_BASIN = 1.0


def assert_no_worse_than_identify(diagnosis: Any, config: Any, records: Sequence[Path], where: Path) -> None:
    """``identify`` with its defaults on ``records`` (into ``where``), then identify's point weighed in the
    diagnosis' problem against the baseline the diagnosis reports: its χ² at most :data:`SAME_BASIN` above
    identify's."""
    res = identify(config, list(records), where, progress=False, export=False)
    problem = diagnosis.problem
    names = problem.space.names
    baseline = diagnosis.report.baseline.parameters

    def chi2(beta: Any) -> float:
        r = problem.residuals(np.asarray(beta, dtype=float))
        return float(r @ r)

    at_identify = chi2([res.best[n] for n in names])
    at_baseline = chi2([baseline[n] for n in names])
    assert at_baseline <= at_identify + SAME_BASIN, \
        f"the diagnosis' baseline χ² {at_baseline:.6g} ({dict(baseline)}) against identify's {at_identify:.6g} " \
        f"({res.best}) in the diagnosis' terms"
