"""numba's cache directory is keyed by every kernel source (``mavlink_bridge.contract.jit_cache``): an edit to a callee
kernel or to a constant a kernel imports gives callers a fresh directory; other edits do not; a user's
``NUMBA_CACHE_DIR`` wins; a child process computes the same directory."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from conftest import REPO_ROOT

from mavlink_bridge.contract import jit_cache
from mavlink_bridge.contract.jit_cache import MARK, cache_key, kernel_sources


def _copy_tree(tmp_path: Path) -> Path:
    root = tmp_path / "src"
    for pkg in jit_cache.PACKAGES:
        shutil.copytree(REPO_ROOT / pkg, root / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    return root


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, (path, old)
    path.write_text(text.replace(old, new, 1))


def test_the_key_covers_callee_kernels_and_imported_constants_and_nothing_else(tmp_path: Path) -> None:
    root = _copy_tree(tmp_path)
    names = {p.relative_to(root).as_posix() for p in kernel_sources(root)}
    # kernels, the kernels they call in other files, the constants and layouts they freeze
    assert {"autopilot/control/cascade_kernel.py", "autopilot/control/pid.py", "autopilot/estimation/ekf_math.py",
            "autopilot/estimation/ekf_layout.py", "mavlink_bridge/contract/geodetic.py", "sim/physics.py",
            "mavlink_bridge/contract/frames.py"} <= names  # fmt: skip
    assert "autopilot/commander/state_machine.py" not in names and "sim/cli.py" not in names
    key = cache_key(root)
    # a callee kernel in another file than its callers (mixer.py's mix_one is called from cascade_kernel.py)
    _edit(
        root / "autopilot/control/mixer.py",
        "from __future__ import annotations",
        "from __future__ import annotations\n#",
    )
    edited = cache_key(root)
    assert edited != key
    _edit(
        root / "autopilot/estimation/ekf_layout.py",
        "from __future__ import annotations",
        "from __future__ import annotations\n#",
    )
    assert cache_key(root) not in (key, edited)  # a layout a kernel imports (no numba of its own)
    after = cache_key(root)
    _edit(
        root / "autopilot/commander/state_machine.py",
        "from __future__ import annotations",
        "from __future__ import annotations\n#",
    )
    assert cache_key(root) == after  # not a kernel's source: the cache stays


def _cache_dir_of_child(env: dict[str, str]) -> str:
    code = "import sim, os; print(os.environ.get('NUMBA_CACHE_DIR', ''))"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO_ROOT, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_children_get_the_keyed_directory_and_a_users_choice_wins(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", MARK)}
    env |= {"XDG_CACHE_HOME": str(tmp_path / "xdg"), "PYTHONPATH": str(REPO_ROOT)}
    keyed = str(tmp_path / "xdg" / "quadsitl" / "numba" / cache_key(REPO_ROOT))
    assert _cache_dir_of_child(env) == keyed and Path(keyed).is_dir()
    stale = {**env, "NUMBA_CACHE_DIR": str(tmp_path / "old"), MARK: str(tmp_path / "old")}
    assert _cache_dir_of_child(stale) == keyed  # one this module chose before: computed again
    mine = str(tmp_path / "mine")
    assert _cache_dir_of_child({**env, "NUMBA_CACHE_DIR": mine}) == mine  # the user's
    # this process (the test run) and its SITL children use the same directory
    assert os.environ.get(MARK) is None or Path(os.environ["NUMBA_CACHE_DIR"]).name == cache_key(REPO_ROOT)
