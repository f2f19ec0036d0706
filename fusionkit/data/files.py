"""Readers and writers for the documented file formats: stream CSV and TUM trajectories."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import DataError
from .plain_text import plain_csv, plain_table
from .stream import POSE_COLUMNS, Stream, check_samples


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise DataError(f"{path}: is a folder; expected a file") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.__class__.__name__}: {exc.strerror or exc})") from None


def _decode(path: Path, data: bytes) -> str:
    """The file's text with \\n line ends, as open() reads it; a byte-order mark (Excel) is dropped."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = exc.object[:exc.start].count(b"\n") + 1
        raise DataError(f"{path}:{line}: cannot read: byte {exc.start} is not UTF-8 text; expected a text file") \
            from None
    return text.replace("\r\n", "\n").replace("\r", "\n") if "\r" in text else text


def _read_text(path: Path) -> str:
    return _decode(path, _read_bytes(path))


# |norm - 1| above this is not rounding: quaternions printed with 4 decimals are within 1e-4 of unit
# norm, so a larger deviation means a scaled or corrupted rotation, worth a note after renormalizing
QUATERNION_NORM_TOLERANCE = 1e-3
# Unix time in seconds stays below 1e10 until the year 2286; a median step above a day is no robot
# stream, while nanosecond stamps of any stream slower than 10 kHz step by 1e5 or more
MAX_SECONDS = 1e11
MAX_MEDIAN_STEP = 1e5
_UNITS = ((1e17, "nanoseconds", "1e9"), (1e14, "microseconds", "1e6"), (MAX_SECONDS, "milliseconds", "1e3"))


def check_seconds(origin: str, t: np.ndarray) -> None:
    """Refuse timestamps that cannot be seconds (see MAX_SECONDS, MAX_MEDIAN_STEP), naming the likely unit."""
    largest = float(np.max(np.abs(t)))
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if largest <= MAX_SECONDS and step <= MAX_MEDIAN_STEP:
        return
    unit, factor = next(((u, f) for limit, u, f in _UNITS if largest > limit), ("nanoseconds", "1e9"))
    raise DataError(f"{origin}: timestamps look like {unit} (t = {t[0]:.10g} .. {t[-1]:.10g}, median step "
                    f"{step:.3g}); fusionkit expects seconds: divide t by {factor}")


def unit_quaternions(q: np.ndarray, origin: str, locate: Callable[[int], str],
                     norms: np.ndarray | None = None) -> str | None:
    """Scale to unit norm, in place, the rows of q (N x 4, qx qy qz qw) whose norm is off 1 by more than
    QUATERNION_NORM_TOLERANCE (the others are left as read); a note counting them (`locate(i)` words
    where row i is), or None. `norms`: np.linalg.norm(q, axis=1), when the caller has it."""
    norms = np.linalg.norm(q, axis=1) if norms is None else norms
    off = np.abs(norms - 1.0)
    bad = off > QUATERNION_NORM_TOLERANCE
    if not bad.any():
        return None
    q[bad] /= norms[bad, None]
    return (f"{origin}: {int(bad.sum())} of {len(q)} quaternions had a norm off 1 by more than "
            f"{QUATERNION_NORM_TOLERANCE:g} (largest {off.max():.3g}, first at {locate(int(np.argmax(bad)))}); "
            "renormalized")


def _is_data(row: list[str]) -> bool:
    """A CSV row that is neither blank nor a `#` comment."""
    return bool(row) and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")


def _check_header(path: Path, line: int, header: list[str]) -> None:
    if header[0] != "t":
        raise DataError(f"{path}:{line}: first column is {header[0]!r}; expected 't' (time in seconds), "
                        f"header was {','.join(header)} (static samples without times: `time: row` on a csv "
                        "source numbers the rows)")
    repeated = sorted({h for h in header if header.count(h) > 1 or not h})
    if repeated:
        raise DataError(f"{path}:{line}: column name(s) {', '.join(map(repr, repeated))} empty or repeated; "
                        f"expected distinct names, header was {','.join(header)}")


def csv_has_time_column(path: Path) -> bool:
    """Whether the CSV's header row starts with `t` (else read_csv_stream(indexed=True) numbers its rows)."""
    with path.open(encoding="utf-8-sig", newline="") as f:
        for row in csv.reader(f):
            if _is_data(row):
                return row[0].strip() == "t"
    return False


def read_csv_header(path: Path, indexed: bool = False) -> tuple[str, ...]:
    """The column names after `t`, reading no further than the header row (to validate before reading data);
    `indexed`: a table that may leave `t` out (read_csv_stream)."""
    try:
        with path.open(encoding="utf-8-sig", newline="") as f:
            reader = csv.reader(f)
            for row in reader:
                if _is_data(row):
                    header = [h.strip() for h in row]
                    if indexed and header[0] != "t":
                        header = ["t", *header]
                    _check_header(path, reader.line_num, header)
                    return tuple(header[1:])
    except (OSError, UnicodeDecodeError):
        _read_text(path)  # raises the located, worded error
        raise
    raise DataError(f"{path}: empty file; expected a header row starting with 't'")


def read_csv_stream(path: Path, name: str, required: tuple[str, ...] = (), indexed: bool = False) -> Stream:
    """CSV with a header row whose first column is `t` (seconds); every cell numeric. `indexed`: a table whose
    rows need no time may leave `t` out, and its rows are then numbered 0, 1, ... as their t."""
    raw = _read_bytes(path)
    plain = plain_csv(raw)
    if plain is None:
        header, data, lines = _csv_rows(path, _decode(path, raw), required, indexed)
    else:
        header, data, first = plain
        lines = first + np.arange(len(data) + 1)
        if indexed and header[0] != "t":
            header, data = ["t", *header], np.column_stack([np.arange(len(data), dtype=float), data])
        _check_columns(path, first, header, required)
    check_samples(data[:, 0], data[:, 1:], str(path), lines=np.asarray(lines[1:]))
    check_seconds(f"{path}:{lines[1]}", data[:, 0])
    stream = Stream(name, data[:, 0], tuple(header[1:]), data[:, 1:], str(path))
    if stream.is_pose:
        q = [stream.columns.index(c) for c in POSE_COLUMNS[3:]]
        quats = stream.values[:, q]
        note = unit_quaternions(quats, str(path), lambda i: f"line {lines[i + 1]}")
        stream.values[:, q] = quats
        stream.notes += [note] if note else []
    return stream


def _check_columns(path: Path, line: int, header: list[str], required: tuple[str, ...]) -> None:
    _check_header(path, line, header)
    missing = [c for c in required if c not in header]
    if missing:
        raise DataError(f"{path}:{line}: missing column(s) {', '.join(missing)}; header has "
                        f"{','.join(header)}, expected at least t,{','.join(required)}")


def _csv_rows(path: Path, text: str, required: tuple[str, ...],
              indexed: bool = False) -> tuple[list[str], np.ndarray, list[int]]:
    """(header, rows, line numbers of the header and the rows) read with the csv module, row by row,
    with a located error for a bad header or row; `indexed`: without a `t` column, the row numbers as t."""
    reader = csv.reader(io.StringIO(text))
    rows, lines = [], []  # data rows and their line numbers (comments and blank lines are skipped)
    for row in reader:
        if _is_data(row):
            rows.append(row)
            lines.append(reader.line_num)
    if not rows:
        raise DataError(f"{path}: empty file; expected a header row starting with 't'")
    header = [h.strip() for h in rows[0]]
    index = indexed and header[0] != "t"
    if index:
        rows = [rows[0]] + [[str(i), *row] for i, row in enumerate(rows[1:])]
        header = ["t", *header]
    _check_columns(path, lines[0], header, required)
    width = len(header)
    data = np.empty((len(rows) - 1, width))
    for i, (row, line) in enumerate(zip(rows[1:], lines[1:])):
        if len(row) != width:
            raise DataError(f"{path}:{line}: row has {len(row) - index} columns; header has {width - index} "
                            f"({','.join(header[index:])})")
        try:
            data[i] = [float(c) for c in row]
        except ValueError:
            j = next(j for j, c in enumerate(row) if not _is_float(c))
            raise DataError(f"{path}:{line}: column {header[j]!r} has {row[j].strip()!r}; expected a number") from None
    return header, data, lines


def write_csv_stream(path: Path, stream: Stream) -> None:
    header = "t," + ",".join(stream.columns)
    np.savetxt(path, np.column_stack([stream.t, stream.values]), delimiter=",", header=header,
               comments="", fmt="%.9g")


TUM_FIELDS = ("t",) + POSE_COLUMNS


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_tum(path: Path, name: str) -> Stream:
    """TUM trajectory: `t x y z qx qy qz qw` per line, space separated, `#` comments."""
    raw = _read_bytes(path)
    plain = plain_table(raw, 8)
    if plain is None:
        a, lines = _tum_rows(path, _decode(path, raw))
    else:
        a, lines = plain[0], plain[1] + np.arange(len(plain[0]))
    norms = np.linalg.norm(a[:, 4:], axis=1)
    if np.any(norms < 1e-9):
        bad = int(np.argmax(norms < 1e-9))
        raise DataError(f"{path}:{lines[bad]}: {int(np.sum(norms < 1e-9))} row(s) have a zero quaternion (first "
                        f"at line {lines[bad]}); expected a unit quaternion qx qy qz qw")
    check_samples(a[:, 0], a[:, 1:], str(path), lines=lines)
    check_seconds(f"{path}:{lines[0]}", a[:, 0])
    note = unit_quaternions(a[:, 4:], str(path), lambda i: f"line {lines[i]}", norms)
    return Stream(name, a[:, 0], POSE_COLUMNS, a[:, 1:], str(path), [note] if note else [])


def _tum_rows(path: Path, text: str) -> tuple[np.ndarray, np.ndarray]:
    """(rows, their line numbers) of a TUM file read line by line, with a located error for a bad line."""
    rows, lines = [], []
    for n, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split()
        if len(parts) != 8:
            raise DataError(f"{path}:{n}: {len(parts)} fields; expected 8 (t x y z qx qy qz qw)")
        try:
            rows.append([float(p) for p in parts])
        except ValueError:
            bad = next(i for i, p in enumerate(parts) if not _is_float(p))
            raise DataError(f"{path}:{n}: field {bad + 1} ({TUM_FIELDS[bad]}) is {parts[bad]!r}; expected a number "
                            "(fields: t x y z qx qy qz qw)") from None
        lines.append(n)
    if not rows:
        raise DataError(f"{path}: no poses; expected lines 't x y z qx qy qz qw'")
    return np.asarray(rows), np.asarray(lines)


def write_tum(path: Path, stream: Stream) -> None:
    a = np.column_stack([stream.t, stream.pose_array()])
    np.savetxt(path, a, fmt="%.9f", header="t x y z qx qy qz qw")
