"""Names that become paths: one rule for every config, registry or user name used as a file name.

A scenario name, an estimator label, a world or dataset name ends up in ``trajectories/<name>.tum``
or ``plots/map_<name>.png``. Such a name must be one plain file-name component, so that no
config can write outside its results folder (``../../x``), replace a hidden bookkeeping file
(``.slamkit-results``) or produce a name the file system rejects.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterator

from slamkit.errors import ConfigError, OutputError

#: longest accepted component (most file systems allow 255 bytes; suffixes need room)
MAX_COMPONENT_CHARS = 200


def path_component(name: object, what: str) -> str:
    """``name`` if it is one plain file-name component, else a ConfigError naming ``what``.

    Refused: non-strings, '', '.', '..', a leading '.', '/' or '\\\\', NUL and other control
    characters, and names longer than :data:`MAX_COMPONENT_CHARS`."""
    if not isinstance(name, str):
        raise ConfigError(f"{what} must be a string to be used as a file name, got {name!r}")
    problem = None
    if name in ("", ".", ".."):
        problem = "it is empty or a relative folder reference"
    elif "/" in name or "\\" in name:
        problem = "it contains a path separator"
    elif name.startswith("."):
        problem = "it starts with '.' (hidden files are slamkit's bookkeeping)"
    elif any(ord(c) < 32 or ord(c) == 127 for c in name):
        problem = "it contains a control character"
    elif len(name) > MAX_COMPONENT_CHARS:
        problem = f"it is longer than {MAX_COMPONENT_CHARS} characters"
    if problem is not None:
        raise ConfigError(f"{what} {name!r} cannot be used as a file name: {problem}; "
                          "use a plain name such as 'office_tour'")
    return name


def file_in(folder: str | Path, stem: str, suffix: str, what: str) -> Path:
    """``folder/<stem><suffix>`` after checking that ``stem`` is one plain component."""
    return Path(folder) / f"{path_component(stem, what)}{suffix}"


def check_output_file(path: str | Path, is_ours, what: str) -> Path:
    """``path`` (absolute) if slamkit may write the single output file there: it does not exist,
    or it is a regular file that ``is_ours(path)`` recognises as one slamkit writes (a recording,
    a sequence file). A folder, a symbolic link or someone else's file is an OutputError and is
    left untouched."""
    from slamkit.errors import OutputError

    path = Path(os.path.abspath(path))
    if path.is_symlink():
        raise OutputError(f"{path} is a symbolic link; choose another {what} path")
    if not path.exists():
        return path
    if not path.is_file():
        raise OutputError(f"{path} exists and is not a file; choose another {what} path")
    try:
        ours = bool(is_ours(path))
    except OSError:
        ours = False
    if not ours:
        raise OutputError(f"{path} exists and is not a {what} slamkit wrote; slamkit will not "
                          "replace it: remove it or choose another path")
    return path


def check_no_file_above(path: str | Path, hint: str = "choose another --out") -> None:
    """An OutputError when an existing ancestor of ``path`` is not a folder (``--out
    file.txt/sub``): nothing can be created under it, and ``mkdir`` would fail with an OSError
    deep in the writer. Missing ancestors are fine (the writer creates them)."""
    final = Path(os.path.abspath(path))
    for parent in final.parents:
        if parent.is_dir():
            return
        if parent.exists() or parent.is_symlink():
            raise OutputError(f"{final} cannot be created: {parent} is a file, not a folder; {hint}")


def temporary_sibling(path: Path) -> Path:
    """A unique hidden name beside ``path`` to assemble it under (never a user's file name)."""
    import uuid

    return path.with_name(f".{path.name}.partial-{uuid.uuid4().hex[:8]}")


@contextlib.contextmanager
def atomic_file(path: Path) -> Iterator[Path]:
    """Write a file under a temporary sibling name (the context's value) and rename it to
    ``path`` when the block completes, so ``path`` holds either its old content or the whole new
    file; on an error the partial file is removed."""
    tmp = temporary_sibling(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def publish_umask_mode(path: Path) -> None:
    """Give a file assembled with a private mode (``mkstemp`` makes 0600) the mode an ordinary
    ``open()`` would have given it under the process umask."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)
