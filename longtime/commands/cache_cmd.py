"""``longtime cache info|clear``: the folders the suite keeps between runs.

``info`` lists each folder (the generated kernels, the heyoka references and, when
$NUMBA_CACHE_DIR is set, numba's cache folder) with its number of files and bytes.
``clear`` removes the kernels (the generated modules, numba's cache of them beside them
and their entries in $NUMBA_CACHE_DIR) and the references, or only those asked for with
``--kernels`` / ``--references``, and prints what it removed. Every file there is rebuilt
on demand; the kernels need no clearing after an edit (their names fingerprint the code
they run, see ``longtime.core.jitcache``), only to reclaim space.
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from longtime.core.cache import cache_root

KERNEL_PREFIX = "longtime_kernel_"  # the generated modules' names, and numba's cache files of them


def _folders() -> dict[str, Path]:
    root = cache_root()
    folders = {"kernels": root / "kernels", "reference": root / "reference"}
    if os.environ.get("NUMBA_CACHE_DIR"):
        folders["numba"] = Path(os.environ["NUMBA_CACHE_DIR"])
    return folders


def _files(folder: Path, pattern: str = "*") -> list[Path]:
    return [f for f in folder.rglob(pattern) if f.is_file()] if folder.is_dir() else []


def _size(files: list[Path]) -> int:
    total = 0
    for f in files:
        try:
            total += f.stat().st_size
        except FileNotFoundError:  # removed meanwhile by another process
            pass
    return total


def _human(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError("unreachable")


def cmd_info(args) -> int:
    rows = []
    for name, path in _folders().items():
        files = _files(path)
        rows.append({"folder": name, "path": str(path), "files": len(files), "bytes": _size(files)})
    if args.format == "json":
        print(json.dumps({"root": str(cache_root()), "folders": rows}, indent=2))
        return 0
    width = max(len(r["path"]) for r in rows)
    for r in rows:
        print(f"{r['folder']:<10} {r['path']:<{width}}  {r['files']:>7} files  {_human(r['bytes']):>9}")
    return 0


def _remove(files: list[Path], label: str) -> None:
    size = _size(files)
    for f in files:
        f.unlink(missing_ok=True)
    print(f"removed {len(files)} file{'' if len(files) == 1 else 's'} ({_human(size)}) {label}")


def cmd_clear(args) -> int:
    both = not (args.kernels or args.references)
    folders = _folders()
    if args.kernels or both:
        kernels = folders["kernels"]
        _remove(_files(kernels), f"from {kernels}")
        shutil.rmtree(kernels, ignore_errors=True)  # the emptied __pycache__ folders
        if "numba" in folders:
            _remove(_files(folders["numba"], KERNEL_PREFIX + "*"),
                    f"of generated kernels from numba's cache {folders['numba']}")
    if args.references or both:
        reference = folders["reference"]
        _remove(_files(reference), f"from {reference}")
        shutil.rmtree(reference, ignore_errors=True)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("cache", help="the cache folders (kernels, references): info, clear",
                              description=__doc__.split("\n\n")[1])
    sub = p.add_subparsers(dest="cache_command", required=True, metavar="ACTION")
    info = sub.add_parser("info", help="each cache folder with its number of files and bytes")
    info.add_argument("--format", choices=["table", "json"], default="table")
    info.set_defaults(func=cmd_info)
    clear = sub.add_parser("clear", help="remove cached kernels and references (default: both)")
    clear.add_argument("--kernels", action="store_true", help="only the compiled kernels")
    clear.add_argument("--references", action="store_true", help="only the reference solutions")
    clear.set_defaults(func=cmd_clear)
