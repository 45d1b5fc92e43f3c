"""The one line-splitting rule and the one number-token rule of every slamkit text reader.

Lines end at ``"\\n"``; a ``"\\r"`` just before it is dropped (files written on Windows). No other
character ends a line: ``str.splitlines()`` also breaks at form feed, vertical tab, ``\\x1c-\\x1e``,
NEL (U+0085), U+2028 and U+2029, and ``open()``'s universal newlines at a lone ``"\\r"``, which
shifts every line number an error message gives after such a character. Here such characters stay
inside their line (whitespace to ``str.split()``), so line N is what ``sed -n Np`` shows.

A number token is ASCII: sign, digits, ``.``, exponent, or nan/inf/infinity (the readers then
reject non-finite values with their own message). Python's ``float()`` also takes ``1_000`` and
any Unicode decimal digit (Arabic-Indic ``\\u0663``, full-width ``\\uff11``); ``numpy.loadtxt`` and
the compiled scanner ``slamkit/data/formats/_textscan.c`` do not, so without this rule a file would
read differently depending on which path parsed it. For ASCII text without ``_`` the three accept
exactly the same tokens, which is how :func:`float_table` stays vectorised.

This is a base module (like :mod:`slamkit.errors`): readers in every layer (``slamkit.data``,
``slamkit.maps.movingai``) share it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slamkit.errors import DataError


def split_lines(text: str) -> list[str]:
    """Lines of ``text``: split at ``"\\n"`` only, one trailing ``"\\r"`` per line dropped; a final
    line break does not start an extra empty line."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]


def read_bytes(path: str | Path) -> bytes:
    """The bytes of ``path``; a missing file or a folder is a ``DataError`` naming it."""
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise DataError("no such file", path) from None
    except IsADirectoryError:
        raise DataError("is a directory, not a file", path) from None


def read_text(path: str | Path, encoding: str = "utf-8") -> str:
    """The text of ``path`` with no newline translation; a missing file, a folder or undecodable
    bytes are a ``DataError`` naming the file."""
    path = Path(path)
    data = read_bytes(path)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise DataError(f"not a text file ({exc.reason} at byte {exc.start})", path, line) from None


def read_lines(path: str | Path, encoding: str = "utf-8") -> list[str]:
    """:func:`read_text` split by :func:`split_lines`."""
    return split_lines(read_text(path, encoding))


def is_number_token(token: str) -> bool:
    """True for an ASCII decimal number or nan/inf/infinity (see the module docstring)."""
    if not token.isascii() or "_" in token:
        return False
    try:
        float(token)
    except ValueError:
        return False
    return True


def parse_number(token: str, what: str, path: str | Path | None = None, line: int | None = None) -> float:
    """``float(token)`` under the shared token rule; otherwise a ``DataError`` naming ``what``."""
    if not is_number_token(token):
        raise DataError(f"{what} is {token!r}, expected a number", path, line)
    return float(token)


def parse_int(token: str, what: str, path: str | Path | None = None, line: int | None = None) -> int:
    """An ASCII decimal integer (optional sign); otherwise a ``DataError`` naming ``what``."""
    body = token[1:] if token[:1] in "+-" else token
    if not (body.isascii() and body.isdigit()):
        raise DataError(f"{what} is {token!r}, expected an integer", path, line)
    return int(token)


def float_table(rows: list[list[str]], lines: list[int] | np.ndarray, path: str | Path,
                field: str = "field") -> np.ndarray:
    """(K, n) floats of equally long token rows; the first token breaking the shared rule is a
    ``DataError`` naming its line and one-based field."""
    text_ok = all(token.isascii() and "_" not in token for row in rows for token in row)
    if text_ok:
        try:
            return np.array(rows, dtype=float).reshape(len(rows), -1)
        except ValueError:
            pass
    for lineno, row in zip(list(lines), rows):
        for col, token in enumerate(row, start=1):
            parse_number(token, f"{field} {col}", path, int(lineno))
    raise DataError("could not convert values", path)  # pragma: no cover - the loop finds it


def number_rows(path: str | Path, width: int, empty: str, header_lines: int = 0,
                delimiter: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(one-based line numbers (K,), finite values (K, width)) of a whitespace-separated table
    (``delimiter``: another separator, e.g. ``","``, with blanks around tokens ignored); ``#``
    starts a comment, blank lines and the first ``header_lines`` lines are skipped, no rows at
    all is ``DataError(empty)``."""
    lines, rows = [], []
    for lineno, line in enumerate(read_lines(path), start=1):
        if lineno <= header_lines:
            continue
        body = line.split("#", 1)[0]
        if not body.strip():
            continue
        tokens = body.split() if delimiter is None else [t.strip() for t in body.split(delimiter)]
        if len(tokens) != width:
            raise DataError(f"expected {width} numbers, got {len(tokens)}", path, lineno)
        lines.append(lineno)
        rows.append(tokens)
    if not rows:
        raise DataError(empty, path)
    values = float_table(rows, lines, path)
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise DataError("NaN or infinity", path, lines[int(np.flatnonzero(bad)[0])])
    return np.asarray(lines, dtype=np.int64), values
