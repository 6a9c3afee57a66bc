"""The beam's modes: the undamped family continued in the axial load, one parameter set's modes, attachments by rank-one
updates, coupled damping, modal analysis and truncation for control design."""
