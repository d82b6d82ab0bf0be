"""CSV text of the recorded formats as numbers: pandas' fast C parser for a plain
table of numbers (:func:`parse_numbers`), else a careful reader that names the row and
the cell of anything malformed (:func:`parse_rows`);
:mod:`pronet.recorded.recordings` reads every CSV file through them."""

from __future__ import annotations

import io
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

_LINE_STARTING_BLANK = re.compile(r"\n[ \t\f\v]")


def parse_numbers(text: str, width: int) -> F64 | None:
    """The data rows of ``text`` (after its one-line header) as a ``(rows, width)``
    float array, with pandas' C parser (exact, as ``float()``); None unless every row
    is ``width`` finite-or-infinite numbers (a NaN, a short or long row, a cell that is
    not a number, a quoted header: the careful reader then decides)."""
    import pandas as pd

    first = text.partition("\n")[0]
    # pandas would skip a line of blanks that the careful reader reports as a short row:
    # any line starting with a blank goes to the careful reader (a quick scan)
    if '"' in first or _LINE_STARTING_BLANK.search(text):
        return None
    try:
        table = pd.read_csv(
            io.StringIO(text), header=None, skiprows=1, dtype=np.float64, na_filter=False
        ).to_numpy(dtype=np.float64)
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError):
        return None
    if table.ndim != 2 or table.shape[1] != width or table.shape[0] == 0 or np.isnan(table).any():
        return None
    return table


def parse_rows(
    path: Path,
    header: list[str],
    reader: Iterator[list[str]],
    columns: list[int],
    blank_ok: set[int] | None = None,
) -> F64:
    """The ``columns`` of the data rows, cell by cell: a row of the wrong width or a
    cell of those columns that ``float()`` refuses is a ValueError naming the file,
    the row and the column; an empty cell of a column in ``blank_ok`` is NaN."""
    blank = blank_ok or set()
    body = [r for r in reader if r]
    if not body:
        raise ValueError(f"{path}: has a header but no data rows")
    out = np.empty((len(body), len(columns)))
    width = len(header)
    for r, row in enumerate(body, start=1):
        if len(row) != width:
            raise ValueError(f"{path}, row {r}: has {len(row)} fields, the header {width}")
        for j, i in enumerate(columns):
            try:
                out[r - 1, j] = np.nan if i in blank and not row[i].strip() else float(row[i])
            except ValueError:
                raise ValueError(
                    f"{path}, row {r}: {header[i].strip()!r} is {row[i]!r}, not a number"
                ) from None
    return out
