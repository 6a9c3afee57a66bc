"""How often the identification's sign, level, units and grid hints fire where they are false (issue 71: under 1 %).

The family (``tests/hint_family.py``): 64 broadband records, a quarter each correct, with a withheld effect, with an
undeclared delay and with an undeclared anti-alias filter on the sensor channels — every one read with its true
sign and in its true units, the truth inside the newcomer's bounds, so every sign, level or units hint on it is
false.  Each record is taken to where a successful default ``identify`` ends: the records' start, the fit polished
from the truth's parameters with the noise model estimated there, the numerics the records ask for
(:func:`identification.numerics.refine_numerics`) — the search's own failures are the first-records tests'
(``tests/test_first_records.py``) — and the hints are what ``identify`` prints there
(:func:`identification.fit_hints.fit_hints`, the start's level note included where the fit bears it out; the grid's
line and the numerical share's, :func:`identification.numerics.grid_adequacy`, checked by refits on the model's grid
and a finer one, ``tests/grid_truth.py``).  The
records with a withheld effect or a mangled channel end far above the floor (30–7,500 noise variances on some
sensor), which is where a gain that removes half the misfit could be mistaken for units.

Rate: under 1 % of 64 records is none.  Measured before the start's notes were gated to the final fit: the start
itself read a level outside the bounds on 5 records and a reversed sign on 3 (each with a withheld effect or a
mangled channel); the fit-gated hints fired on one: a gain of 1.04 on a sensor behind an undeclared filter at
0.43 fs removed 66 % of its misfit (6 → 2.7 noise variances) and was called "units or calibration" — a gain is now
named only when it removes 80 % (:data:`identification.fit_hints.REMOVES`; a record in mm: 95 %).  The same family
through a full default ``identify`` is ``benchmarks/bench_hint_rates.py``.  On the way the family found a
``ValueError`` in the noise model on a correct record (a noise shape overflowing across the band; now the white
floor, :mod:`identification.noise_model`).
"""
from __future__ import annotations

import numpy as np
import pytest

from ebb_model.space.adequacy import grid_line
from grid_truth import false_grid_claims, grid_claims, grid_truth
from hint_family import KINDS, hint_bench, write_hint_case
from identification.basins import noise_at
from identification.data_start import data_start
from identification.fit_hints import fit_hints
from identification.native import NativeEvaluator
from identification.numerics import grid_adequacy, refine_numerics
from identification.parameters import parameter_space
from identification.polish import polish
from identification.run import _arrays, load_identification_config, read_data
from identification.runners import SerialRunner

FAMILY = 64
CHUNKS = 4


def _hints_at_the_optimum(i: int, folder) -> tuple[list[str], dict[str, float]]:
    """The hints ``identify`` prints on record ``i`` at the end of a successful search (module docstring) — its
    grid claims among them where refits contradict them (``tests/grid_truth.py``) — and the fit's gap per sensor
    in noise variances."""
    case = hint_bench(i)
    cfg_path, rec_path = write_hint_case(case, folder)
    cfg = load_identification_config(cfg_path)
    exps = read_data(cfg, [rec_path])
    space = parameter_space(cfg)

    def evaluator_for(c):
        return NativeEvaluator(c, space, _arrays(c, exps), stabilising=False)

    evaluator = evaluator_for(cfg)
    start = data_start(evaluator)
    x0 = np.array([case.bench.truth[n] for n in space.names])
    noise = noise_at(evaluator, x0)
    assert noise is not None, case.name
    runner = SerialRunner()
    r = polish(evaluator, x0, noise=noise, max_evaluations=200)
    f = np.asarray(runner(evaluator, r.x[None, :]))[0]
    evaluator, polished, _ = refine_numerics(evaluator, [(-1, r.x, f, r.n_evaluations, r)], runner, 200, noise,
                                             evaluator_for)
    simulated = evaluator.simulate(polished[0][1]).outputs
    whitened = np.concatenate([noise.whiten(k, e.outputs - s) for k, (e, s) in enumerate(zip(exps, simulated))])
    gap = dict(zip(cfg.output_names, map(float, np.mean(whitened ** 2, axis=0))))
    hints = fit_hints(cfg.output_names, [e.outputs for e in exps], simulated, gap, True, start)
    advice, adequacy = grid_adequacy(evaluator, polished[0][1], noise)
    claim, refine = grid_claims(grid_line(advice, adequacy), adequacy.summary())
    false = false_grid_claims(claim, refine, grid_truth(evaluator, polished[0][1], noise, adequacy.shift))
    return hints + false, gap


@pytest.mark.parametrize("chunk", range(CHUNKS))
def test_no_false_sign_level_units_or_grid_hint_on_records_read_right(chunk, tmp_path):
    fired, far = [], 0
    size = FAMILY // CHUNKS
    for i in range(chunk * size, (chunk + 1) * size):
        hints, gap = _hints_at_the_optimum(i, tmp_path / str(i))
        far += max(gap.values()) > 10.0
        if hints:
            fired.append((hint_bench(i).name, hints))
    assert not fired, fired
    # the family reaches where the hints are examined: the records the model does not describe end far above the
    # floor (measured: every record with a withheld effect and all but two with a mangled channel above 10)
    assert far >= size * (len(KINDS) - 1) // len(KINDS) - 3, far
