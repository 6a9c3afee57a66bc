"""Stage 4, the judgement: one verdict from the refits, through an ordered list of rules
(:mod:`~diagnosis.judgement.rules`): naming, numerical adequacy, plausibility, nested cases, evidence and ties,
notes; each rule takes and returns a typed :class:`~diagnosis.judgement.verdict.Verdict`."""
