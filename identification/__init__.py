"""Identification of the beam: experiments, objectives, optimiser, identifiability, exports."""
