"""Stage 1, the baseline: the model without any effect fitted to the records (:mod:`~diagnosis.baseline.fit`),
with the measured force's sign weighed as evidence (:mod:`~diagnosis.baseline.polarity`), under the noise as it is
in each record (:mod:`~diagnosis.baseline.noise`), on the numerics the records ask for
(:mod:`~diagnosis.baseline.numerics`)."""
