"""The root typer app and the one error handler every command runs under.

Exit codes (also in ``slamkit --help`` and the README):

* 0: done;
* 2: bad input -- a malformed file, an invalid config or option, an output path slamkit will not
  write (any :class:`~slamkit.errors.SlamkitError` but the ones below, and typer's usage errors);
* 3: no result -- a valid request without an answer: no path, a failed solve, a non-finite result
  (:class:`~slamkit.errors.NoResultError` and :class:`~slamkit.errors.BackendError`);
* 1: an internal error (any other exception): one line on stderr; ``--debug`` shows the traceback.

Command modules register themselves on ``app`` (see ``slamkit.cli``); none of them catches
exceptions itself.
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
import warnings

import click
import typer
import typer.exceptions
from typer.core import TyperGroup

from slamkit.errors import BackendError, NoResultError, SlamkitError
from slamkit.naming import SlamkitDeprecationWarning

EXIT_OK, EXIT_INTERNAL, EXIT_BAD_INPUT, EXIT_NO_RESULT = 0, 1, 2, 3

EPILOG = ("Exit codes: 0 done, 2 bad input (file, config, option or output path), 3 no result (no "
          "path, failed solve, non-finite result), 1 internal error (run with --debug for the "
          "traceback).")


def exit_code_of(exc: SlamkitError) -> int:
    return EXIT_NO_RESULT if isinstance(exc, (NoResultError, BackendError)) else EXIT_BAD_INPUT


# typer >= 0.20 vendors click (typer._click); older ones use click itself: pass both through
_PASS_THROUGH = tuple({typer.Exit, typer.Abort, click.exceptions.Exit, click.exceptions.Abort,
                       click.ClickException, *(c for c in (getattr(typer.exceptions, "TyperException", None),)
                                               if c is not None)})


@contextlib.contextmanager
def _deprecations_as_one_line():
    """An old spelling a user typed (``rrt-star``) is reported as ``warning: ...`` on stderr,
    every time, without Python's file:line prefix."""
    with warnings.catch_warnings():
        previous = warnings.showwarning
        warnings.simplefilter("always", SlamkitDeprecationWarning)

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, SlamkitDeprecationWarning):
                typer.echo(f"warning: {message}", err=True)
            else:
                previous(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


class _SlamkitGroup(TyperGroup):
    """Runs every (sub)command under one handler: no traceback reaches the user unless asked."""

    def invoke(self, ctx: click.Context):
        try:
            with _deprecations_as_one_line():
                return super().invoke(ctx)
        except _PASS_THROUGH:
            raise
        except SlamkitError as exc:
            if ctx.params.get("debug"):
                raise
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(exit_code_of(exc)) from None
        except KeyboardInterrupt:
            typer.echo("interrupted", err=True)
            raise typer.Exit(130) from None
        except Exception as exc:  # noqa: BLE001 - the one place that turns bugs into one line
            if ctx.params.get("debug"):
                raise
            first = str(exc).splitlines()[0] if str(exc) else ""
            typer.echo(f"internal error: {type(exc).__name__}: {first} (run again with --debug for the "
                       "traceback, and please report it)", err=True)
            raise typer.Exit(EXIT_INTERNAL) from None


app = typer.Typer(
    name="slamkit",
    cls=_SlamkitGroup,
    help="Mobile-robot estimation as optimisation: pose-graph SLAM, filters vs smoothers, "
    "planning, control, evaluation and Rerun recordings.",
    epilog=EPILOG,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="show the full traceback of an error")) -> None:
    """Mobile-robot estimation as optimisation."""


def _checked(value: float | None, lower: float | None, strict: bool) -> float | None:
    if value is None:
        return None
    if not math.isfinite(value):
        raise typer.BadParameter(f"must be a finite number, got {value}")
    if lower is not None and (value <= lower if strict else value < lower):
        raise typer.BadParameter(f"must be {'>' if strict else '>='} {lower:g}, got {value:g}")
    return value


def finite(value: float | None) -> float | None:
    """Option callback: a finite number (no nan, inf)."""
    return _checked(value, None, False)


def positive(value: float | None) -> float | None:
    """Option callback: a finite number > 0."""
    return _checked(value, 0.0, True)


def non_negative(value: float | None) -> float | None:
    """Option callback: a finite number >= 0."""
    return _checked(value, 0.0, False)


def _strict(value):
    """NaN and inf become null: strict JSON has neither (json.dumps would write NaN/Infinity)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


def dumps_json(obj, indent: int | None = None) -> str:
    """The one way every ``--json`` output is written: strict JSON, never NaN or Infinity."""
    return json.dumps(_strict(obj), indent=indent, allow_nan=False)


def run() -> None:
    """The console entry point."""
    sys.exit(app())
