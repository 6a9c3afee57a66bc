"""Stage 7, the corrected model: the baseline plus the named effect, refitted, exported as config, StateSpace and
FMU (:mod:`~diagnosis.corrected.export`)."""
