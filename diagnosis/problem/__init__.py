"""The gap problem every stage works on: the records split into fit and held-out windows
(:mod:`~diagnosis.problem.records`), the beam with effects attached (:mod:`~diagnosis.problem.augmented`, the
axial terms in :mod:`~diagnosis.problem.axial_modal` and :mod:`~diagnosis.problem.axial_terms`), and its
whitened residuals and least-squares fits (:mod:`~diagnosis.problem.fitting`)."""
