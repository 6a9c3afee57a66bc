"""Stage 3, the search: the candidates refitted with the baseline unknowns — shortlist, modal pattern, other
basins, continuation, nested special cases and pairs (:mod:`~diagnosis.search.rank` orders the work; the shared
state is :mod:`~diagnosis.search.state`, the refits run on :mod:`~diagnosis.search.workers`)."""
