"""Where numba caches the compiled kernels: a directory named by a hash of every source they are built from.

numba's ``cache=True`` re-checks only the file a kernel is defined in, so a cached caller keeps the machine code of a
callee kernel (or a constant, such as ``ekf_layout``'s indices or ``GRAVITY_M_S2``) from another file as it was when
the caller was compiled. Here the cache directory (``NUMBA_CACHE_DIR``) is
``${XDG_CACHE_HOME:-~/.cache}/quadsitl/numba/<key>``, ``key`` a sha256 over the kernel modules (every module of
``sim``, ``autopilot`` and ``mavlink_bridge`` that imports numba) and every project module they import, transitively:
an edit to any of them gives a new, empty directory, and everything is compiled afresh (``tools.warm_jit``).

Imported first by ``sim``, ``autopilot`` and ``mavlink_bridge`` (their ``__init__``), so it runs before numba reads
its configuration; SITL children compute the same key (and re-compute it, an inherited directory is not trusted).
A ``NUMBA_CACHE_DIR`` the user set wins. Key directories unused for :data:`PRUNE_AFTER_S` are removed.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import sys
import time
from pathlib import Path

PACKAGES = ("sim", "autopilot", "mavlink_bridge")
#: Set beside NUMBA_CACHE_DIR when this module chose it (so a child re-computes it; a user's value has no mark).
MARK = "QUADSITL_NUMBA_CACHE_DIR"
PRUNE_AFTER_S = 14 * 86400.0
_NUMBA = re.compile(r"^\s*(?:import numba|from numba[\s.])", re.M)
_IMPORT = re.compile(
    r"^[ \t]*(?:from\s+((?:sim|autopilot|mavlink_bridge|\.+\w*)(?:\.\w+)*)\s+import\s+(\([^)]*\)|[\w ,]+)|"
    r"import[ \t]+((?:sim|autopilot|mavlink_bridge)(?:\.\w+)*))",
    re.M,
)


def _module_file(root: Path, module: str) -> Path | None:
    """The source of ``module`` under ``root`` (a module or a package's ``__init__``), None when it is not one."""
    path = root.joinpath(*module.split("."))
    for candidate in (path.with_suffix(".py"), path / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _absolute(module: str, importer: Path) -> str:
    """``module`` as written in ``importer`` (a path relative to the root), relative imports made absolute."""
    level = len(module) - len(module.lstrip("."))
    if level == 0:
        return module
    package = importer.parent.parts[: len(importer.parent.parts) - (level - 1)]
    return ".".join((*package, module[level:])).rstrip(".")


def kernel_sources(root: Path) -> list[Path]:
    """The kernel modules under ``root`` and the project modules they import (transitively), sorted."""
    sources = {p: p.read_text(encoding="utf-8") for pkg in PACKAGES for p in (root / pkg).rglob("*.py")}
    todo = [p for p, text in sources.items() if _NUMBA.search(text)]
    seen = set(todo)
    while todo:
        path = todo.pop()
        for match in _IMPORT.finditer(sources[path]):
            module = _absolute(match.group(1) or match.group(3), path.relative_to(root))
            names = re.findall(r"\w+", match.group(2) or "")  # ``from pkg import module`` names a module too
            for dep in (_module_file(root, m) for m in (module, *(f"{module}.{n}" for n in names))):
                if dep is not None and dep in sources and dep not in seen:
                    seen.add(dep)
                    todo.append(dep)
    return sorted(seen)


def cache_key(root: Path) -> str:
    """sha256 (hex, 16 digits) over the kernel sources' paths (relative to ``root``) and bytes."""
    digest = hashlib.sha256()
    for path in kernel_sources(root):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def cache_root() -> Path:
    """``${XDG_CACHE_HOME:-~/.cache}/quadsitl/numba``: one directory per key below it."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "quadsitl" / "numba"


def configure(root: Path | None = None) -> Path | None:
    """Point numba's cache at this source tree's key directory (None: a user's NUMBA_CACHE_DIR, or no writable
    cache directory, in which case numba's default applies)."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given and given != os.environ.get(MARK):
        return None  # the user's choice
    root = root or Path(__file__).resolve().parents[2]
    try:
        key_dir = cache_root() / cache_key(root)
        key_dir.mkdir(parents=True, exist_ok=True)
        os.utime(key_dir)  # in use: pruning keeps it
    except OSError:
        return None
    os.environ["NUMBA_CACHE_DIR"] = os.environ[MARK] = str(key_dir)
    if "numba" in sys.modules:  # imported before us: make it read the directory before any kernel is decorated
        sys.modules["numba"].core.config.reload_config()
    _prune(key_dir)
    return key_dir


def _prune(keep: Path) -> None:
    """Remove key directories of other sources untouched for PRUNE_AFTER_S (best effort)."""
    now = time.time()
    try:
        stale = [d for d in keep.parent.iterdir() if d != keep and now - d.stat().st_mtime > PRUNE_AFTER_S]
    except OSError:
        return
    for d in stale:
        shutil.rmtree(d, ignore_errors=True)


configure()
