"""A seeded mutation fuzzer for slamkit's readers and config loaders (issue 10).

Every reader and config kind is fuzzed the same way: start from a real, valid file, apply one to
three seeded mutations (byte flips, truncation, deleted/duplicated/swapped lines, numbers replaced
by ``nan``/``inf``/``1e308``/``1_000``/non-ASCII digits, YAML aliases and tags, non-UTF-8 bytes,
form feed and NEL line breaks, 32-bit extremes in binary headers), run the target on the result
under a time limit and classify what happened:

* ``ok``: the target returned and the result passed the target's own check;
* ``clean_error``: a :class:`slamkit.errors.SlamkitError` (the message is what a user reads);
* ``traceback``: any other exception -- a defect;
* ``hang``: the time limit was hit -- a defect;
* ``nonfinite``: the target returned, but its check found an impossible number -- a defect.

Use::

    report = fuzz(read_tum, seed_bytes, suffix=".tum", cases=200, seed=0, workdir=tmp_path)
    assert report.defects == [], report.summary()

The report keeps the first few defect cases with their exception, so a failing test says what
input broke which line.
"""

from __future__ import annotations

import dataclasses
import math
import re
import signal
import traceback
from collections import Counter
from pathlib import Path
from typing import Any, Callable

import numpy as np

from slamkit.errors import SlamkitError

NUMBER_RE = re.compile(rb"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
HOSTILE_NUMBERS = [b"nan", b"NaN", b"inf", b"-inf", b".nan", b".inf", b"1e308", b"-1e308", b"1e20",
                   b"-1", b"0", b"-0", b"0.0", b"abc", b"", b"1_000", "\u0663".encode(),
                   "\uff11".encode(), b"99999999999999999999999", b"1e-320", b"0x10", b"True"]
HOSTILE_SNIPPETS = [b"\xff\xfe", b"\x00", b"\x0c", "\u0085".encode(), b"\r", b"\t", b" &a [*a]",
                    b" !!python/object/apply:os.system ['true']", b"{", b"[", b": :", b"- -",
                    b" *undefined", b"\n---\n", b"\n...\n", b"'", b'"', b"#", b"\\", b"~"]
BINARY_INTS = [b"\xff\xff\xff\xff", b"\x7f\xff\xff\xff", b"\x00\x00\x00\x00", b"\x80\x00\x00\x00",
               b"\x00\x00\x75\x30"]  # 0x7530 = 30000: a plausible but huge image dimension

OUTCOMES = ("ok", "clean_error", "traceback", "hang", "nonfinite")


class _Timeout(BaseException):
    """Raised by the alarm; a BaseException so that ``except Exception`` in a target cannot eat it."""


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def mutate_once(data: bytes, rng: np.random.Generator, binary: bool) -> bytes:
    """One seeded mutation of ``data``."""
    n = len(data)
    if n == 0:
        return bytes(rng.choice(list(HOSTILE_SNIPPETS)))
    ops = ["flip", "delete_span", "insert_bytes", "truncate"]
    ops += ["binary_int"] * 2 if binary else ["number", "number", "number", "del_line", "dup_line",
                                              "swap_lines", "snippet", "splice_token"]
    op = ops[int(rng.integers(len(ops)))]
    pos = int(rng.integers(n))
    if op == "flip":
        b = bytearray(data)
        b[pos] ^= 1 << int(rng.integers(8))
        return bytes(b)
    if op == "delete_span":
        return data[:pos] + data[pos + int(rng.integers(1, 17)):]
    if op == "insert_bytes":
        return data[:pos] + bytes(rng.integers(0, 256, int(rng.integers(1, 9)), dtype=np.uint8)) + data[pos:]
    if op == "truncate":
        return data[:pos]
    if op == "binary_int":
        word = BINARY_INTS[int(rng.integers(len(BINARY_INTS)))]
        return data[:pos] + word + data[pos + len(word):]
    if op == "number":
        matches = list(NUMBER_RE.finditer(data))
        if not matches:
            return data + HOSTILE_NUMBERS[int(rng.integers(len(HOSTILE_NUMBERS)))]
        m = matches[int(rng.integers(len(matches)))]
        return data[:m.start()] + HOSTILE_NUMBERS[int(rng.integers(len(HOSTILE_NUMBERS)))] + data[m.end():]
    if op == "snippet":
        return data[:pos] + HOSTILE_SNIPPETS[int(rng.integers(len(HOSTILE_SNIPPETS)))] + data[pos:]
    if op == "splice_token":
        tokens = re.findall(rb"[A-Za-z_][A-Za-z0-9_]*", data)
        if not tokens:
            return data
        return data[:pos] + b" " + tokens[int(rng.integers(len(tokens)))] + data[pos:]
    lines = _lines(data)
    i = int(rng.integers(len(lines)))
    if op == "del_line":
        del lines[i]
    elif op == "dup_line":
        lines.insert(i, lines[i])
    elif op == "swap_lines":
        j = int(rng.integers(len(lines)))
        lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines)


def mutate(data: bytes, rng: np.random.Generator, binary: bool = False) -> bytes:
    """One to three seeded mutations of ``data``."""
    for _ in range(int(rng.integers(1, 4))):
        data = mutate_once(data, rng, binary)
    return data


def has_nonfinite(value: Any, _depth: int = 0) -> bool:
    """True when ``value`` (numbers, arrays, mappings, sequences, dataclasses) holds NaN or inf."""
    if _depth > 20:
        return False
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, np.integer)):
        return False
    if isinstance(value, (float, np.floating)):
        return not math.isfinite(float(value))
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "fc" and not bool(np.isfinite(value).all())
    if isinstance(value, dict):
        return any(has_nonfinite(v, _depth + 1) for v in value.values())
    if isinstance(value, (list, tuple)):
        return any(has_nonfinite(v, _depth + 1) for v in value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return any(has_nonfinite(getattr(value, f.name), _depth + 1) for f in dataclasses.fields(value))
    return False


@dataclasses.dataclass
class FuzzReport:
    """Counts per outcome and the first few defect cases (input bytes and the exception)."""

    name: str
    counts: Counter = dataclasses.field(default_factory=Counter)
    examples: list[tuple[str, bytes, str]] = dataclasses.field(default_factory=list)
    max_examples: int = 5

    @property
    def defects(self) -> list[tuple[str, bytes, str]]:
        return self.examples

    @property
    def defect_count(self) -> int:
        return self.counts["traceback"] + self.counts["hang"] + self.counts["nonfinite"]

    def record(self, outcome: str, case: bytes, detail: str) -> None:
        self.counts[outcome] += 1
        if outcome in ("traceback", "hang", "nonfinite") and len(self.examples) < self.max_examples:
            self.examples.append((outcome, case[:400], detail[-1500:]))

    def summary(self) -> str:
        head = f"{self.name}: " + ", ".join(f"{k} {self.counts[k]}" for k in OUTCOMES)
        parts = [head]
        for outcome, case, detail in self.examples:
            parts.append(f"--- {outcome} on input {case!r}\n{detail}")
        return "\n".join(parts)


def fuzz(target: Callable[[Path], Any], seed_bytes: bytes, *, suffix: str, cases: int, seed: int,
         workdir: Path, name: str | None = None, binary: bool = False, timeout_s: float = 10.0,
         check: Callable[[Any], str | None] | None = None,
         prepare: Callable[[Path, bytes], Path] | None = None) -> FuzzReport:
    """Run ``target(path)`` on ``cases`` seeded mutations of ``seed_bytes``.

    ``prepare(workdir, mutated) -> path`` writes the case (default: ``workdir/case<suffix>``), for
    formats that need companion files. ``check(result)`` returns a description of an impossible
    result or None (default: any NaN/inf in the result is impossible).
    """
    rng = np.random.default_rng(seed)
    report = FuzzReport(name or getattr(target, "__name__", "target"))
    check = check or (lambda r: "non-finite number in the result" if has_nonfinite(r) else None)
    workdir.mkdir(parents=True, exist_ok=True)

    def _alarm(signum, frame):  # pragma: no cover - only on a hang
        raise _Timeout()

    previous = signal.signal(signal.SIGALRM, _alarm)
    try:
        for _ in range(cases):
            case = mutate(seed_bytes, rng, binary)
            if prepare is not None:
                path = prepare(workdir, case)
            else:
                path = workdir / f"case{suffix}"
                path.write_bytes(case)
            signal.setitimer(signal.ITIMER_REAL, timeout_s)
            try:
                result = target(path)
            except _Timeout:
                report.record("hang", case, f"no answer within {timeout_s} s")
                continue
            except SlamkitError:
                report.record("clean_error", case, "")
                continue
            except RecursionError:
                report.record("traceback", case, traceback.format_exc(limit=3))
                continue
            except Exception:
                report.record("traceback", case, traceback.format_exc())
                continue
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            problem = check(result)
            if problem:
                report.record("nonfinite", case, problem)
            else:
                report.record("ok", case, "")
    finally:
        signal.signal(signal.SIGALRM, previous)
    return report
