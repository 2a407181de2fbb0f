"""Reading a trajectory file's bytes one way only: the header (canonical JSON without
duplicate keys, overflow or deep nesting, type-checked fields, the integrity digest) and
the samples (a strict decimal grammar, block by block).  docs/validation.md, "One parse".
Nothing physical is checked here: that is the validator's job."""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np

from sixplus3 import fileio
from sixplus3.control.file.file_format import COLUMNS, FORMAT, MAX_BYTES, _canonical, digest
from sixplus3.errors import TrajectoryFileError

#: One number of a sample row: the decimal grammar that C's strtod, numpy and pandas
#: read alike (no underscores, no hex, no inf/nan, no spaces, no leading '+' or '.').
NUMBER = r"-?(?:0|[1-9][0-9]*)(?:\.[0-9]+)?(?:[eE][+-]?[0-9]+)?"
_ROW = re.compile(rb"%s(?:,%s){%d}" % (NUMBER.encode(), NUMBER.encode(), len(COLUMNS) - 1))
#: Deepest nesting of the header JSON (the writer's is 4).
MAX_HEADER_DEPTH = 16
#: Rows parsed per block: the text of a block is the only copy of it in memory.
PARSE_BLOCK = 65536


class _HeaderError(ValueError):
    pass


def _no_constants(token: str) -> float:
    raise _HeaderError(f"{token} is not a number JSON allows")


def _finite_float(token: str) -> float:
    value = float(token)
    if not math.isfinite(value):
        raise _HeaderError(f"{token[:40]} overflows to infinity")
    return value


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _HeaderError(f"the key {key[:40]!r} appears twice")
        out[key] = value
    return out


def json_one_meaning(text: str) -> Any:
    """``text`` as JSON read one way only: a ValueError for a duplicate key, NaN,
    Infinity or a number that overflows (the trajectory header's and the drive log's
    header's rule)."""
    return json.loads(text, parse_constant=_no_constants, parse_float=_finite_float,
                      object_pairs_hook=_unique_keys)


def parse_header(line: bytes, name: str = "trajectory") -> dict[str, Any]:
    """The header of a trajectory file's first line (without ``# FORMAT ``), parsed one
    way only: JSON without duplicate keys, NaN, Infinity or overflowing numbers, at most
    :data:`MAX_HEADER_DEPTH` deep, and byte for byte the canonical form the writer makes
    (sorted keys, no spaces, shortest round-trip numbers).  So every reader sees the same
    header, and the digest, computed over the canonical form, covers line 1's exact
    bytes."""
    try:
        header = json_one_meaning(line.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        what = "nests too deep" if isinstance(exc, RecursionError) else str(exc)[:120]
        raise TrajectoryFileError(f"{name}: the header is not valid JSON of one meaning "
                                  f"({what})", value=what,
                                  valid="JSON without duplicate keys, NaN or Infinity") \
            from None
    if not isinstance(header, dict):
        raise TrajectoryFileError(f"{name}: the header is not a JSON object",
                                  value=type(header).__name__, valid="an object")
    if fileio.depth(header, MAX_HEADER_DEPTH) > MAX_HEADER_DEPTH:
        raise TrajectoryFileError(f"{name}: the header nests deeper than {MAX_HEADER_DEPTH}",
                                  value=None, valid=f"<= {MAX_HEADER_DEPTH} levels")
    try:
        canonical = _canonical(header)
    except (TypeError, ValueError, RecursionError):
        canonical = b""
    if canonical != line:
        raise TrajectoryFileError(
            f"{name}: line 1 is not the canonical JSON of its header (sorted keys, no "
            "spaces, shortest numbers), so readers could disagree on it: it was not "
            "written by sixplus3, or was edited", value=line[:60],
            valid="the writer's canonical JSON")
    return header


def header_number(header: dict[str, Any], key: str, name: str, lo: float, hi: float,
                  integer: bool = False) -> float:
    """``header[key]`` as a finite number in [lo, hi] (an int if ``integer``); a
    TrajectoryFileError naming the field and its range otherwise."""
    value = header.get(key)
    ok = (isinstance(value, int) if integer else isinstance(value, (int, float))) \
        and not isinstance(value, bool)
    number = float(value) if ok else math.nan  # type: ignore[arg-type]
    if not lo <= number <= hi:
        kind = "an integer" if integer else "a number"
        raise TrajectoryFileError(f"{name}: header field {key} must be {kind} in "
                                  f"[{lo:g}, {hi:g}], got {fileio.short_repr(value, 60)}",
                                  value=value, valid=f"{kind} in [{lo:g}, {hi:g}]")
    return number


def parse(raw: bytes, name: str = "trajectory") -> tuple[dict[str, Any], np.ndarray]:
    """Header and samples (n, 47) of a trajectory file's bytes, format-checked and
    integrity-checked (nothing physical: that is the validator's job)."""
    nl = raw.find(b"\n")
    prefix = f"# {FORMAT} ".encode()
    if nl < 0 or not raw.startswith(prefix):
        if raw.startswith(prefix) or raw.startswith(b"# sixplus3-trajectory/2 "):
            why = " (line 1 is cut off: a truncated file)"
        elif raw.startswith(b"t,") or raw.startswith(b"# sixplus3-trajectory/"):
            why = " (an older format: re-plan it)"
        else:
            why = ""
        raise TrajectoryFileError(f"{name}: not a {FORMAT} file{why}",
                                  valid=f"first line '# {FORMAT} {{header}}'", value=raw[:40])
    header = parse_header(raw[len(prefix):nl], name)
    if header.get("format") != FORMAT:
        raise TrajectoryFileError(f"{name}: the header does not declare format {FORMAT}",
                                  value=fileio.short_repr(header.get("format"), 60),
                                  valid=FORMAT)
    body = memoryview(raw)[nl + 1:]  # no copy
    integ = header.get("integrity")
    if not isinstance(integ, dict) or integ.get("algorithm") != "sha256" \
            or not isinstance(integ.get("digest"), str):
        raise TrajectoryFileError(f"{name}: the header has no sha256 integrity digest",
                                  value=fileio.short_repr(integ, 80),
                                  valid="{algorithm: sha256, digest}")
    if digest(header, body) != integ.get("digest"):
        raise TrajectoryFileError(f"{name}: integrity digest mismatch: the header or the "
                                  "samples were edited, truncated or corrupted",
                                  value=integ.get("digest"),
                                  valid="the SHA-256 of the header and samples")
    ncol = len(COLUMNS)
    want = (",".join(COLUMNS) + "\n").encode()
    if bytes(body[:len(want)]) != want:
        raise TrajectoryFileError(f"{name}: line 2 must be the {ncol} column names "
                                  f"{','.join(COLUMNS[:3])},...,{COLUMNS[-1]}",
                                  value=bytes(body[:80]), valid=",".join(COLUMNS))
    n = int(header_number(header, "samples", name, 2, MAX_BYTES // (2 * ncol), True))
    header_number(header, "rate_hz", name, 0.0, 1e9)
    header_number(header, "duration_s", name, 0.0, 1e9)
    if header.get("columns") != COLUMNS:
        raise TrajectoryFileError(f"{name}: header field columns does not match the samples",
                                  value=fileio.short_repr(header.get("columns"), 80),
                                  valid="the 47 column names")
    data = _parse_rows(raw, nl + 1 + len(want), n, name)
    if not math.isclose(float(header["duration_s"]), data[-1, 0], abs_tol=1e-12):
        raise TrajectoryFileError(f"{name}: header duration differs from the last sample",
                                  value=header.get("duration_s"), valid=float(data[-1, 0]))
    return header, data


def _parse_rows(raw: bytes, pos: int, n: int, name: str) -> np.ndarray:
    """The (n, 47) samples of the rows that start at ``raw[pos]``, each ending in a
    newline, parsed block by block: every number must match :data:`NUMBER`."""
    ncol = len(COLUMNS)
    data = np.empty((n, ncol))
    k = 0
    while k < n:
        stop = min(n, k + PARSE_BLOCK)
        lines = []
        for r in range(k, stop):
            e = raw.find(b"\n", pos)
            if e < 0:
                raise TrajectoryFileError(
                    f"{name}: {r} complete sample rows, the header says {n} (a truncated "
                    "file)", value=r, valid=f"{n} rows, each ending in a newline")
            line = raw[pos:e]
            if _ROW.fullmatch(line) is None:
                _bad_row(line, r + 1, name)
            lines.append(line)
            pos = e + 1
        data[k:stop] = np.array(b",".join(lines).split(b","),
                                dtype=np.float64).reshape(stop - k, ncol)
        k = stop
    if pos != len(raw):
        raise TrajectoryFileError(f"{name}: more sample rows than the header's {n}",
                                  value=f"> {n}", valid=f"{n} rows")
    finite = np.isfinite(data)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        raise TrajectoryFileError(f"{name}: non-finite value in column {COLUMNS[c]} at sample "
                                  f"{r} (t = {data[r, 0]:g} s)",
                                  value=float(data[r, c]), valid="finite numbers")
    return data


def _bad_row(line: bytes, row: int, name: str) -> None:
    ncol = len(COLUMNS)
    fields = line.split(b",")
    if len(fields) != ncol:
        raise TrajectoryFileError(f"{name}: sample row {row} does not have {ncol} values",
                                  value=row, valid=f"{ncol} values per row")
    num = re.compile(NUMBER.encode())
    c = next(i for i, f in enumerate(fields) if num.fullmatch(f) is None)
    raise TrajectoryFileError(
        f"{name}: sample row {row}, column {COLUMNS[c]}: {fields[c][:40]!r} is not a plain "
        "decimal number (digits, one '.', an exponent; no '_', '+', hex, inf or nan)",
        value=fields[c][:40].decode("ascii", "replace"), valid=NUMBER)


__all__ = ["MAX_HEADER_DEPTH", "NUMBER", "header_number", "parse", "parse_header"]
