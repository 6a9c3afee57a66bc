"""``--modes FILE``, ``--decay FILE``, ``--ambient FILE``: measured natural frequencies taken as evidence with the
records or alone (``ebb identify`` and ``ebb diagnose``): peaks picked from a measured spectrum
(:mod:`identification.spectrum_modes`), or the modes of a record without a force — a free decay or an ambient
record (:mod:`identification.output_record`)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ebb_model.config import BeamConfig

__all__ = ["add_modes_arguments", "config_with_spectrum_modes"]


def add_modes_arguments(parser: argparse.ArgumentParser) -> None:
    """``--modes FILE``, ``--modes-count N``, ``--modes-band LO HI``, ``--modes-model-error R``."""
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--modes", default=None, metavar="FILE",
                        help="a measured spectrum (.lvm or .csv: frequency [Hz], magnitude) whose resonance peaks "
                             "are fitted with the records as measured natural frequencies")
    source.add_argument("--decay", default=None, metavar="FILE",
                        help="a record without a force of the structure left ringing at its first sample (the "
                             "config's sensors' columns): its modes are the measured natural frequencies")
    source.add_argument("--ambient", default=None, metavar="FILE",
                        help="a stationary record without a force, under an unmeasured broadband force (the "
                             "config's sensors' columns): its modes, from its correlations, are the measured "
                             "natural frequencies")
    parser.add_argument("--modes-count", type=int, default=None, metavar="N",
                        help="with --modes: the lowest N peaks (default: the peaks up to the first that breaks "
                             "a beam's widening mode spacing)")
    parser.add_argument("--modes-band", type=float, nargs=2, default=(1.0, float("inf")), metavar=("LO", "HI"),
                        help="with --modes: the band searched for peaks, Hz (default 1 Hz and up)")
    parser.add_argument("--modes-model-error", type=float, default=0.01, metavar="R",
                        help="with --modes: relative frequency error expected of the beam model (default 0.01)")


def config_with_spectrum_modes(args: argparse.Namespace) -> BeamConfig | str:
    """The config path, or with ``--modes`` the loaded config with the spectrum's peaks as its
    ``[identification.modes]`` (each printed); with ``--decay`` or ``--ambient`` the record's modes."""
    kind = "decay" if getattr(args, "decay", None) else "ambient" if getattr(args, "ambient", None) else None
    if kind is not None:
        return _config_with_record_modes(args, kind)
    if args.modes is None:
        return str(args.config)
    from identification.modal_data import with_modes
    from identification.config_file import load_identification_config
    from identification.spectrum_modes import spectrum_modes

    cfg = load_identification_config(args.config)
    try:
        modes = spectrum_modes(Path(args.modes), count=args.modes_count, band_hz=tuple(args.modes_band),
                               model_error=args.modes_model_error)
    except ValueError as exc:
        from ebb_model.errors import ConfigError

        raise ConfigError(f"--modes: {exc}") from None
    if not getattr(args, "quiet", False):
        picked = ", ".join(f"{f:.4g} ± {s:.2g}" for f, s in zip(modes.frequencies_hz, modes.std_hz))
        print(f"measured modes from {args.modes}: {picked} Hz", file=sys.stderr)
    return with_modes(cfg, modes)


def _config_with_record_modes(args: argparse.Namespace, kind: str) -> BeamConfig:
    """The loaded config with the modes of ``--decay`` / ``--ambient``'s record as its ``[identification.modes]``
    (printed with their damping ratios)."""
    from identification.config_file import load_identification_config
    from identification.modal_data import with_modes
    from identification.output_record import record_output_modes

    path = getattr(args, kind)
    cfg = load_identification_config(args.config)
    found = record_output_modes(cfg, Path(path), kind)
    modes = found.modal_data()
    if not getattr(args, "quiet", False):
        picked = ", ".join(f"{f:.5g} ± {s:.2g} Hz (ζ {z:.3g} ± {zs:.2g})" for f, s, z, zs in zip(
            found.frequencies_hz, found.frequency_std, found.damping, found.damping_std))
        what = "a free decay" if kind == "decay" else "an ambient record"
        print(f"measured modes from {path} ({what}): {picked}", file=sys.stderr)
        if found.tones_hz.size:
            lines = ", ".join(f"{f:.5g}" for f in found.tones_hz)
            print(f"not modes: lines at {lines} Hz do not decay (a tone in the force, a machine's harmonic, mains "
                  "pickup): left out", file=sys.stderr)
    return with_modes(cfg, modes)
