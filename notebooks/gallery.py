"""Refresh the gallery: run every ``notebooks/gallery_*.ipynb``, keep its outputs in the
notebook, and copy the pictures and animations it writes to ``docs/gallery/``.

A reader sees the gallery without running anything: the committed notebooks carry their
outputs (plots, the final picture or animation), and ``docs/gallery/`` holds the same files
for the README and ``docs/gallery/README.md``. After changing a notebook, or the solver in a way
that changes what the gallery shows, run from the repository root (needs the test extra:
``pip install ".[test]"``):

    python notebooks/gallery.py              # every gallery notebook
    python notebooks/gallery.py fig02 fig11  # those whose name contains fig02 or fig11

Each notebook runs in a scratch directory, as the test suite runs it
(``tests/test_gallery.py``). Every ``.png`` and ``.gif`` it writes there is copied to
``docs/gallery/``; other files (the ``*_facts.json`` the tests check) are left behind. A
picture over :data:`MAX_BYTES` fails the refresh: the repository keeps them small.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import nbclient
import nbformat

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = ROOT / "notebooks"
PICTURES = ROOT / "docs" / "gallery"
#: Largest picture or animation kept in the repository, in bytes.
MAX_BYTES = 400_000
#: Suffixes of the files copied to docs/gallery/.
SUFFIXES = (".png", ".gif")


def gallery_notebooks(names=()):
    """The gallery notebooks, all or those whose file name contains one of ``names``."""
    paths = sorted(NOTEBOOKS.glob("gallery_*.ipynb"))
    if names:
        paths = [p for p in paths if any(name in p.name for name in names)]
    return paths


def execute(path: Path, workdir: Path, timeout: float = 600.0):
    """Executes the notebook at ``path`` with ``workdir`` as its working directory and returns
    it with its outputs (no per-cell timing metadata, so that a refresh changes only what the
    notebook shows)."""
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=timeout, kernel_name="python3",
                                     record_timing=False,
                                     resources={"metadata": {"path": str(workdir)}})
    client.execute()
    return nb


def refresh(path: Path) -> list:
    """Runs one notebook, writes it back with its outputs and copies its pictures; returns the
    pictures copied."""
    with tempfile.TemporaryDirectory(prefix="peridyn-gallery-") as scratch:
        nb = execute(path, Path(scratch))
        pictures = sorted(p for p in Path(scratch).iterdir() if p.suffix in SUFFIXES)
        if not pictures:
            raise RuntimeError(f"{path.name} wrote no picture or animation")
        for picture in pictures:
            size = picture.stat().st_size
            if size > MAX_BYTES:
                raise RuntimeError(f"{path.name}: {picture.name} is {size} bytes, over "
                                   f"{MAX_BYTES}: make it smaller (fewer frames, pixels)")
        PICTURES.mkdir(parents=True, exist_ok=True)
        for picture in pictures:
            shutil.copy2(picture, PICTURES / picture.name)
    nbformat.write(nb, path)
    return [PICTURES / p.name for p in pictures]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*",
                        help="refresh only notebooks whose file name contains one of these")
    args = parser.parse_args(argv)
    paths = gallery_notebooks(args.names)
    if not paths:
        print(f"no gallery notebook matches {args.names}", file=sys.stderr)
        return 1
    for path in paths:
        start = time.perf_counter()
        pictures = refresh(path)
        listed = ", ".join(f"{p.relative_to(ROOT)} ({p.stat().st_size // 1000} kB)"
                           for p in pictures)
        print(f"{path.name}: {time.perf_counter() - start:.0f} s -> {listed}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
