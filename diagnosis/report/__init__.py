"""Stage 6, the report: the typed result written as ``gap.json`` (:mod:`~diagnosis.report.result`), its
figures (:mod:`~diagnosis.report.figures`, :mod:`~diagnosis.report.plots`) and the HTML page
(:mod:`~diagnosis.report.html`)."""
