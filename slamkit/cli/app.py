"""The root typer app; command modules register themselves on it (see ``slamkit.cli``)."""

import typer

app = typer.Typer(
    name="slamkit",
    help="Mobile-robot estimation as optimisation: pose-graph SLAM, filters vs smoothers, "
    "planning, control, evaluation and Rerun recordings.",
    no_args_is_help=True,
    add_completion=False,
)
