"""Sim-to-real gap diagnosis: where an identified model and measurements disagree,
which unmodelled physical effect explains it, and how far the gap closes once
that effect is modelled (checked on held-out data).

Data flow: identified model + data → :mod:`.localise` (where) →
:mod:`.effects` / :mod:`.augmented` (candidate effects, simulated natively) →
:mod:`.score` (score test) → :mod:`.modal_estimate` / :mod:`.modal_pattern` (measured modes,
each effect's modal pattern) → :mod:`.refits` (refit stages) → :mod:`.rank` (information criteria, held-out
error, the verdict) →
:mod:`.run` (``gap.json`` and report plots).
"""
