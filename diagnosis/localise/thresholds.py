"""Thresholds of the localisation: significance bands and the practical sizes worth naming."""
Z99 = 2.5758293035489004
#: Input PSD below this fraction of its maximum: the bin is "not excited".
EXCITE_REL = 1e-3
#: Practical minimum sizes for naming something in the summary.
MIN_SHIFT = 1e-3          # relative frequency shift
MIN_DAMPING_RATIO = 1.2   # damping ratio measured/model (or its inverse)
MIN_GAIN = 0.05           # relative amplitude change
MIN_PHASE_DEG = 3.0       # phase change [deg]
MIN_RMS_CHANGE = 0.2      # relative RMS change over the record
#: Zero-padding factor of the FRFs used to locate peaks and to build the best linear approximation.
PAD = 4

