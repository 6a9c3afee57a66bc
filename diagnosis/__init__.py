"""Sim-to-real gap diagnosis: where an identified model and measurements disagree,
which unmodelled physical effect explains it, and how far the gap closes once
that effect is modelled (checked on held-out data).

The folders are the stages, in the order :func:`diagnosis.run.diagnose` calls them:

* :mod:`.problem` — the records, the beam with effects attached, residuals and fits (what every stage works on);
* :mod:`.baseline` — the model without effects fitted, the force's sign as evidence;
* :mod:`.effects` — the catalogue of candidate effects (each declares what the engine needs to know of it);
  :mod:`.candidates` — which of them apply to the bench, and their score tests;
* :mod:`.search` — the refits: shortlist, modal pattern, basins, continuation, nested cases, pairs;
* :mod:`.localise` — where the residual lies (sensor, mode, band, time, amplitude);
* :mod:`.judgement` — one verdict through an ordered list of rules;
* :mod:`.report` — ``gap.json``, figures and the HTML page; :mod:`.corrected` — the corrected model's files.

:mod:`.settings` holds every threshold; :mod:`.run` is the orchestrator.
"""
