"""The fast path of the TUM and CSV readers: plain numeric text parsed by numpy in C.

A file is plain when it is ASCII and, after any leading `#` comment and blank lines (and, for CSV,
an unquoted header line), every line holds the same number of numbers and nothing else: no
comment, blank or quoted line. numpy's loadtxt reads such a table at C speed and converts each
number exactly as Python's float() does, so the result is the one the line-by-line readers give.
Anything else returns None, and the caller reads line by line, to say where a line is wrong.
"""

from __future__ import annotations

import io

import numpy as np


def _ascii(data: bytes) -> bytes | None:
    """ASCII `data` with \\n line ends (as open() reads text); None for other bytes."""
    if not data.isascii():
        return None
    return data.replace(b"\r\n", b"\n").replace(b"\r", b"\n") if b"\r" in data else data


def _first_content_line(data: bytes, offset: int = 0, line: int = 1) -> tuple[int, int]:
    """(offset, line number) of the first line from `offset` on that is neither blank nor a `#`
    comment; the offset is len(data) when there is none."""
    while offset < len(data):
        end = data.find(b"\n", offset)
        end = len(data) if end < 0 else end
        s = data[offset:end].strip()
        if s and not s.startswith(b"#"):
            return offset, line
        offset, line = end + 1, line + 1
    return len(data), line


def _rows(data: bytes, offset: int, line: int, width: int, delimiter: str | None) -> np.ndarray | None:
    """The (n, width) rows from line `line` (at `offset`) to the end, when every line is a row."""
    if _first_content_line(data, offset)[0] == len(data) or data.find(b"#", offset) >= 0 \
            or data.find(b'"', offset) >= 0:
        return None
    try:
        a = np.loadtxt(io.BytesIO(data), skiprows=line - 1, delimiter=delimiter, comments=None, ndmin=2,
                       dtype=float)
    except ValueError:
        return None
    lines = data.count(b"\n", offset) + (not data.endswith(b"\n"))
    return a if a.shape == (lines, width) else None


def plain_table(data: bytes, width: int) -> tuple[np.ndarray, int] | None:
    """Whitespace-separated rows of `width` numbers (TUM): (rows, line number of the first row)."""
    text = _ascii(data)
    if text is None:
        return None
    offset, line = _first_content_line(text)
    rows = _rows(text, offset, line, width, None)
    return None if rows is None else (rows, line)


def plain_csv(data: bytes) -> tuple[list[str], np.ndarray, int] | None:
    """A header line and comma-separated rows of as many numbers: (column names as written, stripped;
    rows; line number of the header)."""
    text = _ascii(data)
    if text is None:
        return None
    offset, line = _first_content_line(text)
    end = text.find(b"\n", offset)
    head = text[offset:end].decode("ascii")
    if end < 0 or '"' in head or not head.replace(",", "").strip():  # no rows, quoted, or no names at all
        return None
    header = [h.strip() for h in head.split(",")]
    rows = _rows(text, end + 1, line + 1, len(header), ",")
    return None if rows is None else (header, rows, line)
