"""Thresholds of the localisation: significance bands and the practical sizes worth naming."""
Z99 = 2.5758293035489004
#: Input PSD below this fraction of its maximum: the bin is "not excited".
EXCITE_REL = 1e-3
#: The band over which the model-free noise estimate reads the records: where the input's PSD is within 20 dB of its
#: peak (the response there is the force's; beyond it the records hold the noise and the force's tail alike) ...
NOISE_BAND_REL = 1e-2
#: ... and 20 % beyond the highest mode the model places (a mode's half-power band lies well inside it).
NOISE_BAND_BEYOND_MODE = 1.2
#: A resonance's damping is resolved by an FRF when its half-power bandwidth spans at least this many bins (with
#: fewer the SDOF fit's damping is the window's, not the beam's).
DAMPING_BINS = 3
#: Practical minimum sizes for naming something in the summary.
MIN_SHIFT = 1e-3          # relative frequency shift
MIN_DAMPING_RATIO = 1.2   # damping ratio measured/model (or its inverse)
MIN_GAIN = 0.05           # relative amplitude change
MIN_PHASE_DEG = 3.0       # phase change [deg]
MIN_RMS_CHANGE = 0.2      # relative RMS change over the record
#: Zero-padding factor of the FRFs used to locate peaks and to build the best linear approximation.
PAD = 4

