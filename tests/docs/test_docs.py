"""The documentation site (mkdocs.yml, docs/): it builds with ``--strict`` (a broken link, a
missing page or a reference that no longer resolves fails), its API reference covers every
public package, and every tutorial's code runs as written.

A tutorial is executed as a reader would: its ```python and ```bash blocks in order, in one
fresh folder, the Python blocks in one namespace (a later block sees an earlier block's names),
the shell blocks with the venv's ``bin`` first on ``PATH``; a block titled with a file name
(```python title="my_estimator.py"```) is written to that file, as the reader would save it.
```text blocks are not run (set-up commands, illustrations). The numbers a tutorial claims are asserted in its own code, so a
reader sees the check too.
"""

from __future__ import annotations

import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import slamkit

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```\s*$", re.M | re.S)
TITLE = re.compile(r'title="([^"]+)"')
RUNNABLE = ("python", "bash")


def code_blocks(page: Path) -> list[tuple[str, str]]:
    """(language, code) of every runnable fenced block of a Markdown page, in order; a block
    with a ``title="FILE"`` (how the page shows a file's content) becomes ("file:FILE", content)."""
    blocks = []
    for lang, info, code in FENCE.findall(page.read_text()):
        title = TITLE.search(info)
        if title:
            blocks.append((f"file:{title.group(1)}", code))
        elif lang in RUNNABLE:
            blocks.append((lang, code))
    return blocks


def test_code_blocks_are_found_in_order_and_text_blocks_are_skipped(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text("intro\n```bash\nslamkit --help\n```\n```text\nmake run\n```\n"
                    "```python\nx = 1\n\ny = 2\n```\n```yaml title=\"a.yaml\"\nk: 1\n```\n")
    assert code_blocks(page) == [("bash", "slamkit --help\n"), ("python", "x = 1\n\ny = 2\n"),
                                 ("file:a.yaml", "k: 1\n")]


def top_level_modules() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(slamkit.__path__, "slamkit.")
                  if not m.name.split(".")[-1].startswith("_"))


def test_the_api_reference_covers_every_package_and_every_page_is_in_the_nav() -> None:
    # a package's page renders its submodules too (show_submodules), so a new module appears
    # without editing the docs; a new package needs its page
    referenced = set()
    for page in (DOCS / "reference").glob("*.md"):
        referenced |= set(re.findall(r"^::: (\S+)\s*$", page.read_text(), re.M))
    assert set(top_level_modules()) - referenced == set(), "packages missing from docs/reference"
    assert referenced - set(top_level_modules()) == set(), "docs/reference names modules that are gone"

    def pages(node) -> list[str]:
        if isinstance(node, str):
            return [node]
        if isinstance(node, list):
            return [p for item in node for p in pages(item)]
        return [p for value in node.values() for p in pages(value)]

    nav = pages(yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"])
    on_disk = sorted(str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md"))
    assert sorted(nav) == on_disk


def test_the_site_builds_strict(tmp_path: Path) -> None:
    mkdocs = Path(sys.executable).with_name("mkdocs")
    done = subprocess.run([str(mkdocs), "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-4000:]
    reference = (tmp_path / "site" / "reference" / "systems" / "index.html").read_text()
    # the docstrings were rendered, not only the module names
    assert "Lidar SLAM as a running system" in reference
    for tutorial in (DOCS / "tutorials").glob("*.md"):
        assert (tmp_path / "site" / "tutorials" / tutorial.stem / "index.html").exists()


RUNNER = r'''
import subprocess, sys
namespace = {"__name__": "__tutorial__"}
for index, (lang, code) in enumerate(BLOCKS):
    print(f"--- block {index} ({lang})", flush=True)
    if lang.startswith("file:"):
        open(lang[len("file:"):], "w").write(code)
    elif lang == "python":
        exec(compile(code, f"<block {index}>", "exec"), namespace)
    else:
        subprocess.run(["bash", "-euo", "pipefail", "-c", code], check=True)
'''


def run_page(page: Path, folder: Path, timeout_s: float = 900) -> subprocess.CompletedProcess:
    script = folder / "_tutorial.py"
    script.write_text(f"BLOCKS = {code_blocks(page)!r}\n{RUNNER}")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
               RERUN_ANALYTICS="0")
    return subprocess.run([sys.executable, str(script)], cwd=folder, env=env, capture_output=True,
                          text=True, timeout=timeout_s)


PAGES = sorted([DOCS / "getting-started.md", *(DOCS / "tutorials").glob("*.md")])


@pytest.mark.parametrize("page", PAGES, ids=[p.stem for p in PAGES])
def test_the_page_runs_as_written(page: Path, tmp_path: Path) -> None:
    assert code_blocks(page), f"{page.name} has no runnable code"
    done = run_page(page, tmp_path)
    assert done.returncode == 0, f"{page.name} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
