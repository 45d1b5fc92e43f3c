"""The dataset registry: named public datasets, where their files are, and how to fetch them.

Every dataset (``intel``, ``city10000``, ``torus3d``, ``parking-garage``, ``kitti_00``,
``w10000`` ...) has an entry (:class:`DatasetEntry`): kind, format, files with sha256 and source
address, licence, counts and reference values (published optima flagged ``published=True``; the
MANIFEST's "gtsam local check" numbers flagged ``published=False``). The table itself lives in
``slamkit/data/registry_table.toml`` (package data, read by :mod:`slamkit.data.registry_table`);
``datasets/README.md`` explains the layout.

Files are looked up, first hit wins, in:

1. ``$SLAMKIT_DATA`` -- a folder laid out like ``../shared/datasets`` (gtsam wheel files under
   ``gtsam_data/``);
2. ``<checkout>/../shared/datasets`` (computed from this package's location);
3. the gtsam wheel's ``Data`` folder (found with ``importlib.util.find_spec``; gtsam is not
   imported), for files that come from the wheel;
4. the user cache ``$SLAMKIT_CACHE`` or ``~/.cache/slamkit`` (same layout as 1), which is where
   :func:`fetch` downloads to.

:func:`fetch` downloads each file of an entry from its recorded source with ``urllib`` into a
temporary file in the cache, checks its sha256 and only then renames it into place; on a
mismatch it raises :class:`~slamkit.errors.ChecksumError` and leaves nothing behind. Lookup
does not hash files (that is :func:`verify`).

Sources are recorded as ``raw.githubusercontent.com/<owner>/<repo>/<commit>/<path>`` URLs with the
MANIFEST's abbreviated commit; gtsam wheel files point at a borglab/gtsam commit that holds a
file of that name (or the unpinned ``develop`` branch where we know none) -- in every case the
sha256 is what pins the content.
"""

from __future__ import annotations

import difflib
import hashlib
import importlib.util
import os
import sys
import tempfile
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Mapping

from slamkit.data import registry_table as table
from slamkit.data.pose_graph import PoseGraph
from slamkit.data.trajectory import Trajectory
from slamkit.errors import ChecksumError, ConfigError, DataError, DatasetNotFoundError

if TYPE_CHECKING:
    from slamkit.maps.occupancy_grid import OccupancyGrid
    from slamkit.data.sequence import Sequence

POSE_GRAPH_KINDS = ("pose_graph_2d", "pose_graph_3d")
WHEEL_PREFIX = "gtsam_data/"
_CHUNK = 1 << 16


@dataclass(frozen=True)
class DatasetFile:
    """One file of a dataset. ``path`` is relative to a data root (the shared-datasets layout)."""

    path: str
    sha256: str
    size_bytes: int
    source: str
    url: str
    #: file name inside the gtsam wheel's Data folder, for files that come from the wheel
    wheel_name: str | None = None

    @property
    def name(self) -> str:
        return Path(self.path).name


@dataclass(frozen=True)
class ReferenceValue:
    """A number to compare results with. ``published=False`` marks our own regression anchors."""

    kind: str
    value: float | None
    objective: str
    published: bool
    source: str
    details: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "value": self.value, "objective": self.objective,
                "published": self.published, "source": self.source, "details": dict(self.details)}


@dataclass(frozen=True)
class DatasetEntry:
    name: str
    kind: str
    format: str
    files: tuple[DatasetFile, ...]
    title: str
    licence: str
    counts: Mapping[str, int]
    references: tuple[ReferenceValue, ...]
    ground_truth_file: str | None = None
    ground_truth_format: str | None = None
    notes: str = ""

    @property
    def primary(self) -> DatasetFile:
        return self.files[0]

    @property
    def has_ground_truth(self) -> bool:
        return self.ground_truth_file is not None

    def reference(self, kind: str) -> ReferenceValue | None:
        return next((r for r in self.references if r.kind == kind), None)

    def to_dict(self) -> dict:
        return {
            "name": self.name, "kind": self.kind, "format": self.format, "title": self.title,
            "licence": self.licence, "counts": dict(self.counts), "notes": self.notes,
            "ground_truth": None if self.ground_truth_file is None else
            {"file": self.ground_truth_file, "format": self.ground_truth_format},
            "files": [{"path": f.path, "sha256": f.sha256, "size_bytes": f.size_bytes,
                       "source": f.source, "url": f.url} for f in self.files],
            "references": [r.to_dict() for r in self.references],
        }


# --- building the entries from the table -------------------------------------------------------


def _file(path: str) -> DatasetFile:
    if path.startswith(WHEEL_PREFIX):
        name = path[len(WHEEL_PREFIX):]
        size, sha, commit = table.WHEEL_FILES[name]
        ref = commit or "develop"
        return DatasetFile(
            path=path, sha256=sha, size_bytes=size, wheel_name=name,
            source=f"borglab/gtsam:examples/Data/{name} @ {ref} (copy in the gtsam 4.3.0 wheel)",
            url=f"https://raw.githubusercontent.com/borglab/gtsam/{ref}/examples/Data/{name}",
        )
    size, sha, repo, src_path, commit, blob = table.SHARED_FILES[path]
    return DatasetFile(
        path=path, sha256=sha, size_bytes=size,
        source=f"{repo}:{src_path} @ {commit}" + (f" (git blob {blob})" if blob else ""),
        url=f"https://raw.githubusercontent.com/{repo}/{commit}/{src_path}",
    )


def _local_check(file_name: str) -> ReferenceValue | None:
    row = table.GTSAM_LOCAL_CHECKS.get(file_name)
    if row is None:
        return None
    edges, poses, init, optimizer, error, chi2, iterations, seconds, sesync_f = row
    return ReferenceValue(
        kind="gtsam_local_check", value=error, objective="gtsam_error", published=False,
        source="MANIFEST.md 'gtsam local check' (gtsam 4.3.0 wheel, prior sigma 1e-6 on the first pose, "
               "LM max 1000 it., rel/abs tol 1e-10; best run) -- a regression anchor, NOT a published value",
        details=MappingProxyType({"edges": edges, "poses": poses, "init": init, "optimizer": optimizer,
                                  "chi2": chi2, "iterations": iterations, "time_s": seconds,
                                  "sesync_F_at_optimum": sesync_f}),
    )


def _build() -> dict[str, DatasetEntry]:
    entries = {}
    for name, spec in table.ENTRIES.items():
        files = tuple(_file(p) for p in spec["files"])
        refs = [ReferenceValue(kind=k, value=v, objective=o, published=p, source=s)
                for k, v, o, p, s in spec.get("refs", [])]
        check = _local_check(files[0].name)
        if check is not None and spec["kind"] in POSE_GRAPH_KINDS:
            refs.append(check)
        gt = spec.get("ground_truth")
        entries[name] = DatasetEntry(
            name=name, kind=spec["kind"], format=spec["format"], files=files, title=spec["title"],
            licence=spec["licence"], counts=MappingProxyType(dict(spec.get("counts", {}))),
            references=tuple(refs), ground_truth_file=None if gt is None else gt[0],
            ground_truth_format=None if gt is None else gt[1], notes=spec.get("notes", ""),
        )
    return entries


_ENTRIES: dict[str, DatasetEntry] = _build()
#: every dataset by name (a read-only view: plug-ins join with :func:`register_dataset`)
REGISTRY: Mapping[str, DatasetEntry] = MappingProxyType(_ENTRIES)
#: the entry-point group whose objects are :class:`DatasetEntry` values (a user's own datasets)
ENTRY_POINT_GROUP = "slamkit.datasets"
_discovered = False


def name_key(name: str) -> str:
    """The one naming rule for dataset names: case is ignored and ``_`` and ``-`` are the same
    letter, so ``intel_log``, ``Intel-Log`` and ``intel-log`` name one dataset (the registry keeps
    each under the spelling its source uses: ``kitti_00``, ``parking-garage``)."""
    return str(name).strip().lower().replace("_", "-")


def discover(refresh: bool = False) -> None:
    """Register installed plug-ins' datasets (see :func:`_discover`)."""
    _discover(refresh)


def unregister_dataset(name: str) -> None:
    """Remove a dataset added with :func:`register_dataset`."""
    entry = get(name)
    if entry.name in table.ENTRIES:
        raise ConfigError(f"dataset {entry.name!r} is built in; only a registered one can be removed")
    del _ENTRIES[entry.name]


def register_dataset(entry: DatasetEntry) -> None:
    """Add a user's dataset (a file path in ``entry.files`` may be absolute). A name that the
    naming rule (:func:`name_key`) maps onto a registered one is a ConfigError."""
    if not isinstance(entry, DatasetEntry):
        raise ConfigError(f"register_dataset takes a DatasetEntry (slamkit.data.registry), got {type(entry).__name__}")
    _discover()
    taken = {name_key(n): n for n in _ENTRIES}
    if name_key(entry.name) in taken:
        if _ENTRIES[taken[name_key(entry.name)]] is entry:
            return  # the same object again (imported and found as an entry point)
        raise ConfigError(f"dataset {entry.name!r} is already registered (as {taken[name_key(entry.name)]!r})")
    _ENTRIES[entry.name] = entry


def _discover(refresh: bool = False) -> None:
    """Register the entry points of :data:`ENTRY_POINT_GROUP` and ``$SLAMKIT_PLUGINS`` modules
    (once per process unless ``refresh``)."""
    global _discovered
    if _discovered and not refresh:
        return
    _discovered = True
    import importlib.metadata
    from types import ModuleType

    from slamkit.naming import _import_env_plugins

    _import_env_plugins()
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        where = f"entry point {ep.name!r} = {ep.value!r} (group {ENTRY_POINT_GROUP!r})"
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plug-in names itself
            raise ConfigError(f"{where}: cannot be loaded ({type(exc).__name__}: {exc})") from None
        if isinstance(obj, ModuleType):
            continue
        if not isinstance(obj, DatasetEntry) or name_key(obj.name) != name_key(ep.name):
            raise ConfigError(f"{where}: must name a DatasetEntry called {ep.name!r}, got {obj!r}")
        register_dataset(obj)


# --- where files are ---------------------------------------------------------------------------


def shared_datasets_dir() -> Path:
    """``<checkout>/../shared/datasets``, computed from this file's location."""
    return Path(__file__).resolve().parents[2].parent / "shared" / "datasets"


def gtsam_data_dir() -> Path | None:
    """The gtsam wheel's ``Data`` folder, found without importing gtsam (None if not installed)."""
    try:
        spec = importlib.util.find_spec("gtsam")
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    for location in spec.submodule_search_locations:
        data = Path(location) / "Data"
        if data.is_dir():
            return data
    return None


def cache_dir() -> Path:
    """``$SLAMKIT_CACHE`` or ``~/.cache/slamkit``: where :func:`fetch` writes."""
    env = os.environ.get("SLAMKIT_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "slamkit"


_default_cache_dir = cache_dir  # fetch() has a parameter of the same name


def search_roots() -> list[tuple[str, Path]]:
    """The lookup order as (label, folder); the wheel folder holds files by their wheel name."""
    roots: list[tuple[str, Path]] = []
    env = os.environ.get("SLAMKIT_DATA")
    if env:
        roots.append(("SLAMKIT_DATA", Path(env).expanduser()))
    roots.append(("shared", shared_datasets_dir()))
    wheel = gtsam_data_dir()
    if wheel is not None:
        roots.append(("gtsam_wheel", wheel))
    roots.append(("cache", cache_dir()))
    return roots


def _candidates(f: DatasetFile) -> list[tuple[str, Path]]:
    out = []
    for label, root in search_roots():
        if label == "gtsam_wheel":
            if f.wheel_name is not None:
                out.append((label, root / f.wheel_name))
        else:
            out.append((label, root / f.path))
    return out


def locate(f: DatasetFile) -> tuple[str, Path] | None:
    """(label, path) of the first root holding ``f``, or None."""
    return next(((label, p) for label, p in _candidates(f) if p.is_file()), None)


# --- public API --------------------------------------------------------------------------------


def names() -> list[str]:
    _discover()
    return sorted(REGISTRY)


def get(name: str) -> DatasetEntry:
    """The entry called ``name`` under the naming rule of :func:`name_key` (case ignored, ``_``
    and ``-`` alike); DatasetNotFoundError with suggestions."""
    _discover()
    key = name.strip().lower()
    if key in REGISTRY:
        return REGISTRY[key]
    by_key = {name_key(n): e for n, e in REGISTRY.items()}
    if name_key(key) in by_key:
        return by_key[name_key(key)]
    by_file = [e for e in REGISTRY.values() if e.primary.name.lower() == key]
    if len(by_file) == 1:
        return by_file[0]
    close = difflib.get_close_matches(key, list(REGISTRY), n=4, cutoff=0.6)
    hint = f"; did you mean {', '.join(close)}?" if close else "; `slamkit data list --all` shows every name"
    raise DatasetNotFoundError(f"no dataset named {name!r} in the registry{hint}")


def resolve(name_or_path: str | Path) -> DatasetEntry | Path:
    """The file if ``name_or_path`` names an existing file, else the registry entry of that name.

    A file on disk wins over a registry name of the same spelling (the user pointed at it);
    :func:`resolution_note` says so, for the command to print."""
    if isinstance(name_or_path, Path):
        if name_or_path.is_file():
            return name_or_path
        raise DatasetNotFoundError(f"no such file: {name_or_path}")
    path = Path(name_or_path).expanduser()
    if path.is_file():
        return path
    try:
        return get(name_or_path)
    except DatasetNotFoundError as exc:
        raise DatasetNotFoundError(f"{name_or_path!r} is neither an existing file nor a registry "
                                   f"name ({exc})") from None


def resolution_note(name_or_path: str | Path) -> str | None:
    """A one-line note when ``name_or_path`` is both an existing file and a registry name."""
    if isinstance(name_or_path, Path):
        return None
    try:
        get(str(name_or_path))
    except DatasetNotFoundError:
        return None
    path = Path(name_or_path).expanduser()
    if not path.is_file():
        return None
    return (f"{str(name_or_path)!r} is both a file here and a registry dataset: using the file "
            f"{path.resolve()} (pass the registry name from another folder to use the dataset)")


def _select(entry: DatasetEntry, file: str | None) -> DatasetFile:
    if file is None:
        return entry.primary
    for f in entry.files:
        if file in (f.path, f.name, f.wheel_name):
            return f
    raise DatasetNotFoundError(f"dataset {entry.name!r} has no file {file!r}; its files are "
                               f"{[f.path for f in entry.files]}")


def path_of(name: str, file: str | None = None) -> Path:
    """Local path of a dataset's primary file (or of ``file``: a relative path or file name).

    Raises DatasetNotFoundError listing every location tried."""
    entry = get(name)
    f = _select(entry, file)
    hit = locate(f)
    if hit is not None:
        return hit[1]
    tried = "\n  ".join(f"{label}: {p}" for label, p in _candidates(f))
    raise DatasetNotFoundError(f"{f.path} of dataset {entry.name!r} is not available locally; tried\n  "
                               f"{tried}\n`slamkit data fetch {entry.name}` downloads it into the cache")


def is_available(entry: DatasetEntry) -> bool:
    return all(locate(f) is not None for f in entry.files)


def available() -> list[DatasetEntry]:
    """Entries whose files are all present in some search location, sorted by name."""
    return [REGISTRY[n] for n in names() if is_available(REGISTRY[n])]


def sha256_of(path: str | Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def verify(name: str) -> dict[str, bool | None]:
    """sha256 check of every local file of ``name``: path -> True/False (None: not available)."""
    out: dict[str, bool | None] = {}
    for f in get(name).files:
        hit = locate(f)
        out[f.path] = None if hit is None else sha256_of(hit[1]) == f.sha256
    return out


def ground_truth(name: str) -> Trajectory | None:
    """Ground-truth poses of ``name`` (stamps are vertex ids), or None if the dataset has none."""
    from slamkit.data.formats.ground_truth import read_ground_truth

    entry = get(name)
    if entry.ground_truth_file is None:
        return None
    return read_ground_truth(path_of(entry.name, entry.ground_truth_file), entry.ground_truth_format)


def load_pose_graph_entry(entry: DatasetEntry, policy: str = "keep") -> PoseGraph:
    """Read a registry pose graph with the format the registry records for it."""
    from slamkit.data.formats import POSE_GRAPH_FORMATS, load_pose_graph

    if entry.kind not in POSE_GRAPH_KINDS:
        raise DataError(f"dataset {entry.name!r} is a {entry.kind} dataset, not a pose graph")
    if entry.format not in POSE_GRAPH_FORMATS:
        raise DataError(f"dataset {entry.name!r} has format {entry.format!r}, which no pose-graph reader reads")
    return load_pose_graph(path_of(entry.name), format=entry.format, policy=policy, name=entry.name)


def load_pose_graph_source(name_or_path: str | Path, policy: str = "keep") -> tuple[PoseGraph, DatasetEntry | None]:
    """A pose graph from a registry name or a file path, and the registry entry (None for paths)."""
    from slamkit.data.formats import load_pose_graph

    target = resolve(name_or_path)
    if isinstance(target, DatasetEntry):
        return load_pose_graph_entry(target, policy), target
    return load_pose_graph(target, policy=policy), None


def recording_source(source: str | Path) -> DatasetEntry | Path:
    """What a recording ``source`` names: an existing file, a ROS 2 bag folder (a folder holding
    ``metadata.yaml``), else a registry entry (:func:`resolve`'s errors otherwise)."""
    from slamkit.data.formats.rosbag import is_bag

    path = Path(source).expanduser()
    if path.is_dir():
        if is_bag(path):
            return path
        raise DataError("a folder is not a recording unless it is a ROS 2 bag (it has no metadata.yaml)", path)
    return resolve(source)


def load_recording(source: str | Path, order: str = "log", scan_topic: str | None = None,
                   odom_topic: str | None = None) -> Sequence:
    """A Sequence from a registry laser log (``intel-log``), a CARMEN log file, a .slamseq file,
    a ROS 1 ``.bag`` file or a ROS 2 bag folder (sqlite3 or MCAP storage).

    A CARMEN log's scans come in ``order`` (``log``: as taken; ``stamp``: sorted by ipc stamp,
    see ``slamkit.data.formats.carmen.CarmenLog.to_sequence``); a bag's are in stamp order (as
    it stores them), read by :func:`slamkit.data.formats.rosbag.read_laser_bag` with
    ``scan_topic`` / ``odom_topic`` (chosen automatically when the bag has one of each type)."""
    from slamkit.data.formats.carmen import load_carmen_sequence
    from slamkit.data.formats.rosbag import is_bag, read_laser_bag
    from slamkit.data.formats.sequence import load_sequence

    target = recording_source(source)
    if isinstance(target, Path):
        if is_bag(target):
            return read_laser_bag(target, scan_topic=scan_topic, odom_topic=odom_topic)
        if target.suffix == ".slamseq":
            return load_sequence(target)
        return load_carmen_sequence(target, order=order)
    if target.format != "carmen":
        raise DataError(f"dataset {target.name!r} is a {target.kind} ({target.format}), not a laser log "
                        "or a .slamseq recording")
    return load_carmen_sequence(path_of(target.name), target.name.removesuffix("-log"), order)


def relations_of(name: str) -> Path | None:
    """Local path of a registry laser log's relations file (None when it has none)."""
    entry = get(name)
    rel = [f for f in entry.files if f.path.endswith(".relations")]
    return path_of(entry.name, rel[0].path) if rel else None


def load_grid_map_source(name_or_path: str | Path) -> OccupancyGrid:
    """An occupancy grid from a registry grid map (``arena``, ``den312d`` ...) or a MovingAI
    ``.map`` file (see :func:`resolution_note` for a name that is both)."""
    from slamkit.maps.movingai import load_map

    target = resolve(name_or_path)
    if isinstance(target, Path):
        return load_map(target)
    if target.format != "movingai":
        raise DataError(f"dataset {target.name!r} is a {target.kind} ({target.format}), not a grid map")
    return load_map(path_of(target.name))


# --- fetching ----------------------------------------------------------------------------------


def fetch(name: str, url_override: str | None = None, cache_dir: str | Path | None = None,
          progress: bool | None = None, timeout_s: float = 60.0) -> Path:
    """Download every file of ``name`` that the cache lacks; returns the primary file's path.

    ``url_override`` replaces the recorded source: a full URL for a one-file dataset, or a URL
    ending in ``/`` to which each file name is appended. Each file is streamed into a temporary
    file beside its destination, hashed, and renamed into place only if the sha256 matches
    (ChecksumError otherwise; nothing is left behind). ``progress=None`` shows a rich progress
    bar when stderr is a terminal."""
    entry = get(name)
    root = Path(cache_dir).expanduser() if cache_dir is not None else _default_cache_dir()
    if url_override is not None and len(entry.files) > 1 and not url_override.endswith("/"):
        raise DataError(f"dataset {entry.name!r} has {len(entry.files)} files: give --url as a folder URL "
                        "ending in '/' (each file name is appended)")
    if progress is None:
        progress = sys.stderr.isatty()
    for f in entry.files:
        dest = root / f.path
        if dest.is_file() and sha256_of(dest) == f.sha256:
            continue
        if url_override is None:
            url = f.url
        elif len(entry.files) == 1 and not url_override.endswith("/"):
            url = url_override
        else:
            url = url_override + f.name
        download(url, dest, f.sha256, expected_size=f.size_bytes, progress=progress, timeout_s=timeout_s)
    return root / entry.primary.path


def download(url: str, dest: str | Path, sha256: str, expected_size: int | None = None,
             progress: bool = False, timeout_s: float = 60.0) -> Path:
    """Stream ``url`` to ``dest`` atomically, verifying ``sha256`` before the rename."""
    dest = Path(dest)
    created = [p for p in [dest.parent, *dest.parent.parents] if not p.exists()]
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".part", dir=dest.parent)
    tmp = Path(tmp_name)
    digest = hashlib.sha256()
    try:
        with os.fdopen(fd, "wb") as out:
            if urllib.parse.urlparse(url).scheme not in ("http", "https", "file"):
                raise DataError("only http, https and file URLs can be fetched", url)
            try:
                response = urllib.request.urlopen(url, timeout=timeout_s)  # noqa: S310 (scheme checked)
            except (urllib.error.URLError, OSError, ValueError) as exc:
                raise DataError(f"download failed: {exc}", url) from None
            with response:
                total = expected_size or int(response.headers.get("Content-Length") or 0) or None
                bar = _progress_bar(dest.name, total) if progress else None
                received = 0
                try:
                    while True:
                        chunk = response.read(_CHUNK)
                        if not chunk:
                            break
                        received += len(chunk)
                        if expected_size is not None and received > expected_size:
                            # a wrong or hostile server must not fill the disk: stop at the first
                            # chunk past the recorded size (the sha256 could only say so at the end)
                            raise ChecksumError(f"download exceeds its recorded size of {expected_size} "
                                                "bytes; stopped and discarded", url)
                        out.write(chunk)
                        digest.update(chunk)
                        if bar is not None:
                            bar[0].update(bar[1], advance=len(chunk))
                finally:
                    if bar is not None:
                        bar[0].stop()
        got = digest.hexdigest()
        if got != sha256:
            raise ChecksumError(f"sha256 mismatch: expected {sha256}, got {got}; file discarded", url)
        os.replace(tmp, dest)
        return dest
    except BaseException:
        tmp.unlink(missing_ok=True)
        for folder in created:  # innermost first: remove only folders this call created and left empty
            try:
                folder.rmdir()
            except OSError:
                break
        raise


def _progress_bar(label: str, total: int | None):
    from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn, TransferSpeedColumn

    bar = Progress(TextColumn("{task.description}"), BarColumn(), DownloadColumn(), TransferSpeedColumn(),
                   transient=True)
    task = bar.add_task(label, total=total)
    bar.start()
    return bar, task



def describe(name: str) -> dict:
    """Everything recorded about ``name`` plus where each file is found locally (JSON-ready)."""
    entry = get(name)
    out = entry.to_dict()
    for item, f in zip(out["files"], entry.files):
        hit = locate(f)
        item["location"] = None if hit is None else hit[0]
        item["local_path"] = None if hit is None else str(hit[1])
    out["available"] = all(item["local_path"] is not None for item in out["files"])
    return out
