"""Stage 2, the candidates: which effects of the catalogue apply to this bench
(:mod:`~diagnosis.candidates.catalogue`) and how strongly the baseline's residual asks for each (the score test,
:mod:`~diagnosis.candidates.score`)."""
