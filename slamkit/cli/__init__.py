"""``slamkit`` command line: a thin shell over library functions that return result objects.

Each command group lives in its own module and registers on ``slamkit.cli.app.app``.
"""

from slamkit.cli.app import app
from slamkit.cli import bench as _bench  # noqa: F401
from slamkit.cli import data as _data  # noqa: F401
from slamkit.cli import doctor as _doctor  # noqa: F401
from slamkit.cli import evaluate as _evaluate  # noqa: F401
from slamkit.cli import optimize as _optimize  # noqa: F401
from slamkit.cli import plan as _plan  # noqa: F401
from slamkit.cli import run as _run  # noqa: F401
from slamkit.cli import simulate as _simulate  # noqa: F401
from slamkit.cli import sweep as _sweep  # noqa: F401
from slamkit.cli import view as _view  # noqa: F401


def main() -> None:
    app()
