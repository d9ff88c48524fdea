"""The measured-peaks table of the inverse characterisation (:func:`jaxdea.fit`): a CSV file of
``voltage_V``, ``frequency_Hz`` and optional ``sigma_Hz``, ``m``, ``n``, ``branch`` columns.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

from ..files import atomic_write, read_text

COLUMNS = ("voltage_V", "frequency_Hz", "sigma_Hz", "m", "n", "branch", "torsional",
           "pressure_Pa", "lambda_i", "lambda_z", "width_Hz", "sigma_width_Hz", "quality_factor",
           "sigma_quality_factor")
"""The columns of a peak table, in the order :func:`write_peaks` writes them: the labels, then the
loading of each peak (:data:`jaxdea.studies.fit.LOAD_COLUMNS`; joint fits over several loadings),
then the peak widths (:data:`jaxdea.studies.fit.WIDTH_COLUMNS`: the half-power width in Hz or the
quality factor, and their σ; fits of a damped tube)."""
POSITIVE = ("frequency_Hz", "sigma_Hz", "width_Hz", "sigma_width_Hz", "quality_factor",
            "sigma_quality_factor")
"""Columns whose values must be > 0."""
LABELS = ("m", "n", "branch", "torsional")
LABEL_LOW = dict(m=0, n=1, branch=0, torsional=0)
LABEL_MAX = 2**31 - 1
"""Largest label (m, n or branch) accepted: the range of a 32-bit integer."""
NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)",
                    re.IGNORECASE)
"""A number in a peak table: plain decimal or scientific notation (nan and inf are read, then
refused as not finite)."""


def read_peaks(path) -> dict:
    """Measured peaks from a CSV file: {column: array} for :func:`jaxdea.fit`.

    Columns (header row, any order): ``voltage_V``, ``frequency_Hz`` (> 0), optional ``sigma_Hz``
    (> 0), the optional labels ``m`` (≥ 0), ``n`` (≥ 1), ``branch`` (≥ 0), ``torsional`` (0 or 1)
    and the optional loading of each peak ``pressure_Pa``, ``lambda_i``, ``lambda_z``, the
    optional peak width ``width_Hz`` (half-power, FWHM) or ``quality_factor`` with
    ``sigma_width_Hz`` or ``sigma_quality_factor`` (> 0; a damped tube's fit); lines
    starting with ``#`` and blank lines are skipped; a UTF-8 byte-order mark (Excel's "CSV UTF-8") is accepted.
    Labels are integer arrays, the rest float64.

    Raises:
        ValueError: naming the file, column and line: an unreadable file, an unknown, repeated or
            missing column, a cell that is not a number in plain decimal or scientific notation
            (``2_86.62`` is refused), NaN or ±inf, a frequency or σ ≤ 0, a label that is not an
            integer in [low, LABEL_MAX], a field past ``csv.field_size_limit()``, no data rows.

    Examples:
        >>> peaks = read_peaks("peaks.csv")   # voltage_V,frequency_Hz,sigma_Hz / 2000,41.3,0.2 / …
        >>> peaks["frequency_Hz"], peaks["sigma_Hz"]
        >>> result = jd.fit(peaks, free, fixed)
    """
    path = Path(path)
    try:
        text = read_text(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    lines = [(k + 1, line) for k, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise ValueError(f"{path}: no header row (expected the columns voltage_V, frequency_Hz)")
    rows = []
    for number, line in lines:
        try:
            rows.append(next(csv.reader([line]), []))
        except csv.Error as exc:  # e.g. a field longer than csv.field_size_limit()
            raise ValueError(f"{path}, line {number}: {exc}") from None
    header = [name.strip() for name in rows[0]]
    for name in header:
        if name not in COLUMNS:
            raise ValueError(f"{path}: unknown column {name!r} (allowed: {', '.join(COLUMNS)})")
        if header.count(name) > 1:
            raise ValueError(f"{path}: column {name!r} appears twice")
    for name in COLUMNS[:2]:
        if name not in header:
            raise ValueError(f"{path}: missing the column {name!r} (needs voltage_V, frequency_Hz; "
                             f"optional {', '.join(COLUMNS[2:])})")
    if len(rows) < 2:
        raise ValueError(f"{path}: no data rows below the header")
    columns = {name: [] for name in header}
    for (number, _), row in zip(lines[1:], rows[1:], strict=True):
        if len(row) != len(header):
            raise ValueError(f"{path}, line {number}: {len(row)} fields, the header has "
                             f"{len(header)}")
        for name, cell in zip(header, row, strict=True):
            columns[name].append(_cell(path, number, name, cell.strip()))
    return {name: (np.array(columns[name], dtype=int) if name in LABELS
                   else np.array(columns[name], dtype=np.float64))
            for name in COLUMNS if name in columns}


def _cell(path, number, name, cell):
    where = f"{path}, line {number}, column {name!r}"
    if not NUMBER.fullmatch(cell):  # float() would also take 2_86.62, as 286.62
        raise ValueError(f"{where}: {cell[:40]!r}{'...' if len(cell) > 40 else ''} is not a "
                         "number (plain decimal or scientific notation, e.g. 286.62 or 2.8662e2)")
    value = float(cell)
    if not math.isfinite(value):
        raise ValueError(f"{where}: {cell!r} is not a finite number")
    if name in POSITIVE and value <= 0:
        raise ValueError(f"{where}: {cell}{' Hz' if name.endswith('Hz') else ''}, must be > 0")
    if name in ("lambda_i", "lambda_z") and value <= 0:
        raise ValueError(f"{where}: {cell}, must be > 0")
    if name in LABELS:
        if value != round(value) or not LABEL_LOW[name] <= value <= LABEL_MAX:
            raise ValueError(f"{where}: {cell}, must be an integer >= {LABEL_LOW[name]} and "
                             f"<= {LABEL_MAX}")
        return int(value)
    return value


def write_peaks(path, data) -> Path:
    """Write peaks (a mapping with the columns of :func:`read_peaks`) as CSV; floats are written
    with their shortest exact representation, so :func:`read_peaks` gives them back bit for bit.

    Examples:
        >>> write_peaks("peaks.csv", {"voltage_V": [2e3, 5e3], "frequency_Hz": [41.3, 40.2]})
        >>> read_peaks("peaks.csv")["frequency_Hz"]     # array([41.3, 40.2])
    """
    names = [name for name in COLUMNS if name in data]
    for name in COLUMNS[:2]:
        if name not in names:
            raise ValueError(f"data is missing the column {name!r}")
    columns = [np.asarray(data[name]).ravel() for name in names]
    if any(column.size != columns[0].size for column in columns):
        raise ValueError("data columns must have the same length")
    path = Path(path)
    with atomic_write(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(names)
        for row in zip(*columns, strict=True):
            writer.writerow([str(int(x)) if name in LABELS else repr(float(x))
                             for name, x in zip(names, row, strict=True)])
    return path
