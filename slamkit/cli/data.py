"""``slamkit data list|info|fetch``: the dataset registry from the command line.

Thin shell over :mod:`slamkit.data.registry` (``available``, ``describe``, ``fetch``)."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table

from slamkit.errors import DataError
from slamkit.cli.app import app, dumps_json
from slamkit.data import registry

data_app = typer.Typer(
    name="data",
    help="Named datasets: what is available locally, what is recorded about each, and fetching.",
    no_args_is_help=True,
    add_completion=False,
)
app.add_typer(data_app, name="data")


def list_rows(include_missing: bool = False, verify: bool = False, kind: str | None = None) -> list[dict]:
    """One row per dataset (available ones, or all): name, kind, format, counts, location."""
    rows = []
    for name in registry.names():
        entry = registry.get(name)
        if kind is not None and not entry.kind.startswith(kind):
            continue
        hits = [registry.locate(f) for f in entry.files]
        available = all(h is not None for h in hits)
        if not (available or include_missing):
            continue
        row = {"name": name, "kind": entry.kind, "format": entry.format,
               "poses": entry.counts.get("poses"), "edges": entry.counts.get("edges"),
               "available": available,
               "location": ",".join(sorted({h[0] for h in hits if h is not None})) or None,
               "path": None if hits[0] is None else str(hits[0][1]),
               "ground_truth": entry.has_ground_truth}
        if verify and available:
            row["sha256_ok"] = all(registry.verify(name).values())
        rows.append(row)
    return rows


@data_app.command("list")
def list_cmd(
    all_: bool = typer.Option(False, "--all", help="also list registered datasets not available locally"),
    verify: bool = typer.Option(False, "--verify", help="check the sha256 of every local file"),
    kind: str = typer.Option(None, "--kind", help="only kinds starting with this, e.g. pose_graph, "
                             "pose_graph_3d, landmark, grid_map"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object on stdout"),
) -> None:
    """Datasets available locally (location, format, pose and edge counts)."""
    rows = list_rows(include_missing=all_, verify=verify, kind=kind)
    if as_json:
        typer.echo(dumps_json({"datasets": rows, "search_roots": [
            {"label": label, "path": str(p)} for label, p in registry.search_roots()]}))
        return
    table = Table(title=f"{len(rows)} datasets" + ("" if all_ else " available locally"))
    for column in ("name", "kind", "format", "poses", "edges", "GT", "location"):
        table.add_column(column, justify="right" if column in ("poses", "edges") else "left")
    if verify:
        table.add_column("sha256")
    for r in rows:
        cells = [r["name"], r["kind"], r["format"], "" if r["poses"] is None else f"{r['poses']:,}",
                 "" if r["edges"] is None else f"{r['edges']:,}", "yes" if r["ground_truth"] else "",
                 r["location"] or "[red]missing[/red]"]
        if verify:
            cells.append({True: "ok", False: "[red]MISMATCH[/red]", None: ""}[r.get("sha256_ok")])
        table.add_row(*cells)
    Console(width=max(Console().width, 110)).print(table)


@data_app.command("info")
def info_cmd(
    name: str = typer.Argument(..., help="registry name (e.g. intel, city10000, torus3d), or a ROS bag "
                               "(a ROS 1 .bag file or a ROS 2 bag folder)"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object on stdout"),
) -> None:
    """Everything recorded about a dataset (files, sources, licence, counts, reference values), or
    a ROS bag's topics with their types, message counts and rates."""
    from slamkit.data.formats.rosbag import bag_info, is_bag

    if is_bag(Path(name).expanduser()):
        bag = bag_info(Path(name).expanduser())
        if as_json:
            typer.echo(dumps_json(bag))
            return
        table = Table(title=f"{bag['path']}: {bag['kind']} bag ({bag['storage']}), {bag['messages']:,} "
                            f"messages over {bag['duration_s']:.1f} s")
        for column in ("topic", "type", "count", "rate_hz"):
            table.add_column(column, justify="right" if column in ("count", "rate_hz") else "left")
        for t in bag["topics"]:
            table.add_row(t["topic"], t["type"], f"{t['count']:,}",
                          "" if t["rate_hz"] != t["rate_hz"] else f"{t['rate_hz']:.2f}")
        Console(width=max(Console().width, 110)).print(table)
        return
    info = registry.describe(name)
    if as_json:
        typer.echo(dumps_json(info))
        return
    console = Console()
    console.print(f"[bold]{info['name']}[/bold]: {info['title']}")
    console.print(f"kind {info['kind']}, format {info['format']}, "
                  f"{'available locally' if info['available'] else 'NOT available locally'}")
    if info["counts"]:
        console.print("counts: " + ", ".join(f"{k} {v:,}" for k, v in info["counts"].items()))
    console.print(f"licence: {info['licence']}")
    if info["notes"]:
        console.print(f"notes: {info['notes']}")
    if info["ground_truth"]:
        console.print(f"ground truth: {info['ground_truth']['file']} ({info['ground_truth']['format']})")
    console.print("files:")
    for f in info["files"]:
        where = f"{f['location']}: {f['local_path']}" if f["local_path"] else "[red]not available locally[/red]"
        console.print(f"  {f['path']}  ({f['size_bytes']:,} bytes, sha256 {f['sha256']})", soft_wrap=True)
        console.print(f"    source {f['source']}\n    url    {f['url']}\n    local  {where}", soft_wrap=True)
    if info["references"]:
        console.print("reference values:")
    for r in info["references"]:
        value = "per scenario" if r["value"] is None else f"{r['value']:.6g}"
        flag = "published" if r["published"] else "NOT published (local check)"
        console.print(f"  {r['kind']} = {value} ({r['objective']}), {flag}: {r['source']}", soft_wrap=True)
        if r["details"]:
            console.print("    " + ", ".join(f"{k}={v}" for k, v in r["details"].items()), soft_wrap=True)


@data_app.command("fetch")
def fetch_cmd(
    name: str = typer.Argument(..., help="registry name"),
    url: str = typer.Option(None, "--url", help="download from this URL instead of the recorded source "
                            "(a folder URL ending in '/' for multi-file datasets)"),
    cache_dir: Path = typer.Option(None, "--cache-dir", help="cache folder (default $SLAMKIT_CACHE or "
                                   "~/.cache/slamkit)"),
) -> None:
    """Download a dataset into the cache, verifying every file's sha256."""
    path = registry.fetch(name, url_override=url, cache_dir=cache_dir)
    typer.echo(str(path))


@data_app.command("convert")
def convert_cmd(
    source: str = typer.Argument(..., help="a registry laser log (intel-log, fr079-log, ...), a CARMEN "
                                 ".clf[.gz|.bz2] file or a .slamseq file"),
    out: Path = typer.Argument(..., help="the bag to write (a ROS 2 bag folder; a .bag name writes ROS 1)"),
    storage: str = typer.Option("sqlite3", "--storage", help="ROS 2 storage: sqlite3 (OUT/OUT.db3) or mcap "
                                "(OUT/OUT.mcap)"),
    overwrite: bool = typer.Option(False, "--overwrite", help="replace an earlier bag at OUT (only a bag of the "
                                   "same ROS version)"),
) -> None:
    """Write a recording as a ROS bag (LaserScan, Odometry, Imu, NavSatFix) through rosbags."""
    from slamkit.data.formats.rosbag import check_bag_path, write_bag

    ros_version = 1 if out.suffix == ".bag" else 2
    check_bag_path(out, ros_version, overwrite)  # before the recording is loaded
    # a bag holds its messages in time order: the scans sorted by stamp
    summary = write_bag(out, registry.load_recording(source, order="stamp"),
                        ros_version=ros_version, storage=storage, overwrite=overwrite)
    typer.echo(f"wrote {summary.path}: " + ", ".join(f"{t} {n}" for t, n in summary.messages.items())
               + ("; skipped " + ", ".join(f"{k} {n}" for k, n in summary.skipped_events.items())
                  if summary.skipped_events else ""))


