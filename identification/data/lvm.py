"""LabVIEW measurement files (``.lvm``, text format, Writer_Version 2).

Layout (National Instruments, "Specification of the LabVIEW Measurement File
(.lvm)", NI tutorial 4139)::

    LabVIEW Measurement            <- file header: key<sep>value lines
    Separator   Tab
    Decimal_Separator   .
    X_Columns   One                <- No | One | Multi
    ...
    ***End_of_Header***
                                   <- segment header (one per segment)
    Channels    3
    Y_Unit_Label    Volts   Pounds  g
    X0  0.0E+0 ...
    Delta_X 1.953125E-5 ...
    ***End_of_Header***
    X_Value Voltage Force Acceleratio [Comment]   <- column headings
    0.000000    -0.170586   -3.399325   -0.016694 <- data rows
    ...                                            (further segments may follow)

The reader locates the ``***End_of_Header***`` markers with a regular
expression (no fixed number of header lines), honours ``Separator``,
``Decimal_Separator`` and ``X_Columns``, and parses each data block with
:func:`numpy.loadtxt` (the 63,041-row ARTS-Lab record takes well under a
second).  Segments are concatenated in file order.

Time: with ``X_Columns = One`` the first column (``X_Value``) is the time and
wins over the header's ``X0``/``Delta_X`` -- in the ARTS-Lab record (decimated
from 51.2 kHz to 3200 Hz after acquisition) ``Delta_X`` still says
1.953125e-5 s while the X column steps by 3.125e-4 s.  With ``X_Columns = No``
the time is ``X0 + k * Delta_X`` of each segment.  Units come from
``Y_Unit_Label`` (``"Pounds"``, ``"g"``, ``"Volts"``).
"""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from ebb_model.io.csvio import parse_block
from ebb_model.errors import DataError, DataWarning

from .csv_format import read_text
from .table import RawTable, printed_resolution
from .textblock import column_resolutions, edge_lines

__all__ = ["read_lvm"]

_MARK = re.compile(r"^\*\*\*End_of_Header\*\*\*[^\n]*(?:\n|\Z)", re.MULTILINE)
# a line that starts like a number (LabVIEW writes NaN, Inf, -Inf too)
_NUMERIC_START = r"[ \t]*(?:[-+]?(?:\d|\.\d)|[-+]?nan\b|[-+]?inf)"
_NUMERIC_LINE = re.compile(_NUMERIC_START, re.IGNORECASE)
_TEXT_LINE = re.compile(rf"^(?!{_NUMERIC_START})[ \t]*\S", re.MULTILINE | re.IGNORECASE)
_SEPARATORS = {"tab": "\t", "comma": ","}


def _header(block: str, sep: str | None) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for line in block.split("\n"):
        if not line.strip():
            continue
        s = sep if sep is not None else ("\t" if "\t" in line else ",")
        fields = [f.strip() for f in line.split(s)]
        while len(fields) > 1 and not fields[-1]:
            fields.pop()
        out.setdefault(fields[0], fields[1:])
    return out


def _floats(values: list[str], key: str, source: str, decimal: str) -> list[float]:
    try:
        return [float(v.replace(decimal, ".")) for v in values]
    except ValueError:
        raise DataError(f"{source}: header field {key} is not numeric ({values!r})") from None


def _check_not_open_header(region: str, src: str, first_line: int) -> None:
    """Refuse a segment header that the file ends inside (it starts with ``Channels``, per the spec)."""
    for offset, line in enumerate(region.split("\n")):
        if line.strip():
            if line.split("\t")[0].split(",")[0].strip() == "Channels":
                raise DataError(f"{src}: the segment header starting at line {first_line + offset} is not closed by "
                                "an ***End_of_Header*** line: the file is truncated")
            return
    raise DataError(f"{src}: no data after the last ***End_of_Header*** line (line {first_line - 1}): "
                    "the file is truncated or holds no samples")


def _check_declared_length(hdr: dict[str, list[str]], arr: np.ndarray, x_columns: str, decimal: str, src: str,
                           segment: int) -> None:
    """Compare a segment's rows with its header's ``Samples`` (and ``Delta_X``).

    With ``X_Columns = No`` the rows *are* the samples, so a different count is an
    error.  With an X column, files are often decimated after acquisition without
    updating the header (the ARTS-Lab record), so only data that end before the
    declared duration ``Samples × Delta_X`` are reported, as a :class:`DataWarning`.
    """
    if not hdr.get("Samples"):
        return
    try:
        declared = int(float(hdr["Samples"][0].replace(decimal, ".")))
    except ValueError:
        raise DataError(f"{src}: header field Samples is not a number ({hdr['Samples'][0]!r})") from None
    rows = arr.shape[0]
    if x_columns == "no":
        if rows != declared:
            raise DataError(f"{src}: segment {segment} holds {rows} rows, its header declares Samples = {declared}"
                            + (": the file is truncated" if rows < declared else ""))
        return
    if not hdr.get("Delta_X") or rows < 2:
        return
    dx = _floats(hdr["Delta_X"][:1], "Delta_X", src, decimal)[0]
    span = float(arr[-1, 0] - arr[0, 0])
    step = span / (rows - 1)
    if dx > 0 and span + 1.5 * step < declared * dx:
        warnings.warn(DataWarning(
            f"{src}: segment {segment} ends at {span:.6g} s, its header declares {declared} samples of "
            f"{dx:.6g} s ({declared * dx:.6g} s): truncated file, or a record shortened after acquisition"),
            stacklevel=4)           # the caller of read_lvm (read_lvm -> _read_segments -> here)


def _file_settings(file_hdr: dict[str, list[str]], src: str) -> tuple[str, str, str]:
    """``Separator``, ``Decimal_Separator`` and ``X_Columns`` of the file header (LabVIEW's defaults if absent).

    Parameters
    ----------
    file_hdr
        The file header, from :func:`_header`.
    src
        The file, for messages.

    Returns
    -------
    sep, decimal, x_columns : str
        Column separator (tab or comma), decimal separator, ``"no"``, ``"one"`` or ``"multi"``.

    Raises
    ------
    DataError
        An unsupported value or combination.
    """
    sep_name = (file_hdr.get("Separator") or ["Tab"])[0]
    sep = _SEPARATORS.get(sep_name.lower())
    if sep is None:
        raise DataError(f"{src}: unsupported Separator {sep_name!r}; allowed: Tab, Comma")
    decimal = (file_hdr.get("Decimal_Separator") or ["."])[0] or "."
    if decimal not in (".", ","):
        raise DataError(f"{src}: unsupported Decimal_Separator {decimal!r}; allowed: '.', ','")
    if decimal == "," and sep == ",":
        raise DataError(f"{src}: Decimal_Separator ',' with Separator Comma cannot be parsed")
    x_columns = (file_hdr.get("X_Columns") or ["One"])[0].lower()
    if x_columns not in ("no", "one", "multi"):
        raise DataError(f"{src}: unsupported X_Columns {x_columns!r}; allowed: No, One, Multi")
    return sep, decimal, x_columns


def _split_region(region: str, sep: str, more: bool) -> tuple[tuple[str, ...] | None, int, int | None]:
    """Find the column headings and the data rows in the text after a segment's ``***End_of_Header***``.

    Parameters
    ----------
    region
        The text from the end of the marker to the next marker (or the end of the file).
    sep
        Column separator.
    more
        Whether a further segment follows (its header then ends the data).

    Returns
    -------
    names : tuple of str or None
        The column headings (without a trailing ``Comment``), ``None`` if the first non-blank line
        starts like a number.
    body_start : int
        Start of the data rows in ``region``.
    body_end : int or None
        End of the data rows in ``region`` where the next segment's header starts, ``None`` if the
        data run to the end of ``region``.
    """
    # column headings: first non-blank line, if it does not start like a number
    lead = len(region) - len(region.lstrip("\n \t"))
    lead = region.rfind("\n", 0, lead) + 1
    first_nl = region.find("\n", lead)
    first = region[lead: len(region) if first_nl < 0 else first_nl]
    body_start = lead
    seg_names: tuple[str, ...] | None = None
    if first.strip() and not _NUMERIC_LINE.match(first):
        fields = [f.strip() for f in first.split(sep)]
        while fields and not fields[-1]:
            fields.pop()
        if fields and fields[-1].lower() == "comment":
            fields.pop()
        seg_names = tuple(fields)
        body_start = len(region) if first_nl < 0 else first_nl + 1
    body_end = None
    if more:          # the next segment's header follows the data
        nxt = _TEXT_LINE.search(region, body_start)
        if nxt is not None:
            body_end = nxt.start()
    return seg_names, body_start, body_end


def _default_names(body: str, sep: str) -> tuple[str, ...]:
    """Names ``column0, column1, ...`` for data without headings, as many as the first row has fields.

    Parameters
    ----------
    body
        The data rows.
    sep
        Column separator.

    Returns
    -------
    tuple of str
    """
    first_row = next((ln for ln in body.split("\n", 3) if ln.strip()), "")
    parts = first_row.split(sep)
    while parts and not parts[-1].strip():
        parts.pop()
    return tuple(f"column{j}" for j in range(len(parts)))


def _read_segments(text: str, marks: list[re.Match[str]], sep: str, decimal: str, x_columns: str, src: str
                   ) -> tuple[list[np.ndarray], tuple[str, ...], list[dict[str, list[str]]], tuple[float, ...]]:
    """Parse every segment: its header, column headings and data rows.

    Parameters
    ----------
    text
        The whole file, its line ends ``"\\n"``.
    marks
        The ``***End_of_Header***`` markers; the first ends the file header.
    sep, decimal, x_columns
        The file's settings, from :func:`_file_settings`.
    src
        The file, for messages.

    Returns
    -------
    blocks : list of numpy.ndarray
        The data of each segment, ``(n_rows, n_columns)``.
    names : tuple of str
        Column names (of segment 1).
    seg_headers : list of dict
        The header of each segment (empty without segment headers).
    resolution : tuple of float
        Printed resolution of each column (the coarsest over the segments).

    Raises
    ------
    DataError
        Segments with different columns, malformed rows, a header the file ends inside, no data,
        fewer rows than ``Samples`` declares (``X_Columns = No``).

    Warns
    -----
    DataWarning
        Data with an X column that end before the duration the header declares.
    """
    # marks[0] ends the file header; every further marker ends a segment header.
    # Without a segment header (only one marker) the data follow the file header.
    seg_marks = marks[1:] if len(marks) > 1 else marks[:1]
    cursor = marks[0].end()
    blocks: list[np.ndarray] = []
    names: tuple[str, ...] | None = None
    seg_headers: list[dict[str, list[str]]] = []
    res: tuple[float, ...] | None = None
    for i, m in enumerate(seg_marks):
        seg_hdr = _header(text[cursor:m.start()], sep) if m is not marks[0] else {}
        start = m.end()
        stop = seg_marks[i + 1].start() if i + 1 < len(seg_marks) else len(text)
        region = text[start:stop]
        if i + 1 == len(seg_marks):
            _check_not_open_header(region, src, text.count("\n", 0, start) + 1)
        seg_names, body_start, next_header = _split_region(region, sep, i + 1 < len(seg_marks))
        body_end = len(region)
        if next_header is not None:
            body_end = next_header
            cursor = start + body_end
        body = region[body_start:body_end]
        if decimal == ",":
            body = body.replace(",", ".")
        if seg_names is None:
            seg_names = _default_names(body, sep)
        if names is not None and len(seg_names) != len(names):
            raise DataError(f"{src}: segment {i + 1} has {len(seg_names)} columns, segment 1 has {len(names)}")
        names = names or seg_names
        first_line = text.count("\n", 0, start + body_start) + 1
        arr = parse_block(body, delimiter=sep, names=names, source=src, first_line=first_line,
                          usecols=len(names))
        _check_declared_length(seg_hdr, arr, x_columns, decimal, src, i + 1)
        blocks.append(arr)
        seg_headers.append(seg_hdr)
        r = column_resolutions(edge_lines(body), sep, len(names))
        res = r if res is None else tuple(max(a, b) for a, b in zip(res, r))
    assert names is not None and res is not None
    return blocks, names, seg_headers, res


def _channel_units(seg_headers: list[dict[str, list[str]]], x_columns: str, k: int) -> tuple[str | None, ...]:
    """The unit of each of the ``k`` columns, from segment 1's ``Y_Unit_Label`` (``None``: X columns, none given).

    Parameters
    ----------
    seg_headers
        The segment headers.
    x_columns
        ``"no"``, ``"one"`` or ``"multi"``: which columns are X columns.
    k
        Number of columns.

    Returns
    -------
    tuple of (str or None)
    """
    labels = (seg_headers[0].get("Y_Unit_Label") or []) if seg_headers else []
    if x_columns == "one":
        chan_of = [None] + list(range(k - 1))
    elif x_columns == "multi":
        chan_of = [None if j % 2 == 0 else j // 2 for j in range(k)]
    else:
        chan_of = list(range(k))
    return tuple(labels[c] if c is not None and c < len(labels) and labels[c] else None for c in chan_of)


def _header_time(seg_headers: list[dict[str, list[str]]], blocks: list[np.ndarray], decimal: str,
                 src: str) -> tuple[np.ndarray, float]:
    """The time ``X0 + k * Delta_X`` of every segment (for ``X_Columns = No``), concatenated.

    Parameters
    ----------
    seg_headers, blocks
        The segment headers and data.
    decimal
        Decimal separator.
    src
        The file, for messages.

    Returns
    -------
    time : numpy.ndarray
        Sample times.
    tol : float
        Their error bound from the printed precision of ``X0`` and ``Delta_X``.

    Raises
    ------
    DataError
        A segment header without ``X0`` or ``Delta_X``, or with non-numeric ones.
    """
    tol = 0.0
    pieces = []
    for hdr, arr in zip(seg_headers, blocks):
        if not hdr.get("X0") or not hdr.get("Delta_X"):
            raise DataError(f"{src}: X_Columns = No but the segment header lacks X0 / Delta_X")
        x0 = _floats(hdr["X0"][:1], "X0", src, decimal)[0]
        dx = _floats(hdr["Delta_X"][:1], "Delta_X", src, decimal)[0]
        pieces.append(x0 + dx * np.arange(arr.shape[0]))
        n = arr.shape[0]
        tol = max(tol, 0.5 * printed_resolution(hdr["X0"][:1])
                  + 0.5 * (n - 1) * printed_resolution(hdr["Delta_X"][:1]))
    return np.concatenate(pieces), tol


def read_lvm(path: str | Path) -> RawTable:
    """Read a LabVIEW ``.lvm`` file into a :class:`~identification.data.table.RawTable`.

    Raises
    ------
    DataError
        Not an LVM file, no ``***End_of_Header***`` marker, unsupported
        separator, no data, segments with different columns, malformed rows
        (naming line, sample and column), a header the file ends inside, fewer
        rows than ``Samples`` declares (``X_Columns = No``).

    Warns
    -----
    DataWarning
        Data with an X column that end before the duration the header declares.
    """
    p = Path(path)
    src = str(p)
    text = read_text(p).replace("\r\n", "\n").replace("\r", "\n")
    if not text.lstrip().startswith("LabVIEW Measurement"):
        raise DataError(f"{src}: not a LabVIEW measurement file (first line is not 'LabVIEW Measurement')")
    marks = list(_MARK.finditer(text))
    if not marks:
        raise DataError(f"{src}: the file header is not closed by an ***End_of_Header*** line "
                        "(the file is truncated or not a LabVIEW measurement file)")
    sep, decimal, x_columns = _file_settings(_header(text[: marks[0].start()], None), src)
    blocks, names, seg_headers, res = _read_segments(text, marks, sep, decimal, x_columns, src)
    data = np.vstack(blocks)
    k = len(names)
    units = _channel_units(seg_headers, x_columns, k)
    columns = tuple(np.ascontiguousarray(data[:, j]) for j in range(k))
    time = None
    tol = 0.0
    if x_columns == "no":
        time, tol = _header_time(seg_headers, blocks, decimal, src)
    return RawTable(source=src, kind="column", names=names, columns=columns, units=units, resolution=res,
                    time=time, time_key=0, time_tolerance=tol)
