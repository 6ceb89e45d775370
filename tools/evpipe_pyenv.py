"""Shared helpers for evpipe's Python check/bench scripts (tools/*.py).

* ensure_packages(): makes sure the independent AEDAT 4.0 readers (dv-processing, aedat) and numpy can be
  imported. When they cannot, it creates a virtual environment (default ~/.cache/evpipe-pyenv, or
  $EVPIPE_PYENV), installs them from PyPI and re-runs the calling script inside it. If that fails it exits
  with status 77 and "skipped: <why>" (the automake/CTest convention for a skipped test).
* find_binary(): locates an evpipe executable (evconvert, bench_io) in the usual build folders.
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import sys
from pathlib import Path

SKIP = 77
REPO = Path(__file__).resolve().parent.parent
PACKAGES = ["dv-processing", "numpy", "aedat"]
_MARK = "EVPIPE_PYENV_ACTIVE"


def skip(why: str) -> None:
    print(f"skipped: {why}")
    sys.exit(SKIP)


def _importable(modules: list[str]) -> bool:
    try:
        for m in modules:
            __import__(m)
    except ImportError:
        return False
    return True


def ensure_packages(modules: list[str]) -> None:
    """Re-executes the current script in a venv holding PACKAGES unless `modules` import already."""
    if _importable(modules):
        return
    if os.environ.get(_MARK):
        skip(f"Python packages {', '.join(modules)} still not importable inside {sys.prefix}")
    venv = Path(os.environ.get("EVPIPE_PYENV", Path.home() / ".cache" / "evpipe-pyenv"))
    python = venv / "bin" / "python"
    try:
        if not python.exists():
            print(f"creating a Python environment in {venv} ...", file=sys.stderr)
            subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, stdout=subprocess.DEVNULL)
        probe = subprocess.run([str(python), "-c", "import " + ", ".join(modules)], capture_output=True)
        if probe.returncode != 0:
            print(f"installing {' '.join(PACKAGES)} into {venv} ...", file=sys.stderr)
            subprocess.run([str(python), "-m", "pip", "install", "-q", *PACKAGES], check=True)
    except (OSError, subprocess.CalledProcessError) as e:
        skip(f"cannot install {' '.join(PACKAGES)} into {venv}: {e}")
    env = dict(os.environ)
    env[_MARK] = "1"
    os.execve(str(python), [str(python), *sys.argv], env)


def find_binary(name: str, explicit: str | None = None, env_var: str | None = None,
                build: str | None = None) -> Path | None:
    """An evpipe executable: the explicit path, $env_var, the given build folder, then build folders in and
    next to the repository (Release builds first, then the newest), then PATH."""
    for candidate in (explicit, os.environ.get(env_var) if env_var else None):
        if candidate:
            p = Path(candidate)
            return p if p.exists() else None
    found = []
    patterns = [f"{build}/**/{name}"] if build else [f"{REPO}/build*/**/{name}", f"{REPO.parent}/build*/**/{name}"]
    for pattern in patterns:
        for path in glob.glob(pattern, recursive=True):
            p = Path(path)
            if p.is_file() and os.access(p, os.X_OK):
                found.append(p)
    if not found:
        on_path = shutil.which(name)
        return Path(on_path) if on_path else None

    def rank(p: Path) -> tuple[int, float]:
        cache = next((d / "CMakeCache.txt" for d in p.parents if (d / "CMakeCache.txt").exists()), None)
        release = cache is not None and "CMAKE_BUILD_TYPE:STRING=Release" in cache.read_text(errors="replace")
        return (0 if release else 1, -p.stat().st_mtime)

    return sorted(found, key=rank)[0]


def default_recording() -> Path:
    return REPO.parent / "shared" / "data" / "real" / "emlb-demo-01" / "demo-01.aedat4"


def read_with_dv(path: Path):
    """Events of an AEDAT 4.0 file read by dv-processing's MonoCameraRecording, as an (n, 4) int64 array
    (t, x, y, p), with the resolution (w, h) and the time range (first, last) from the file's data table.
    Needs ensure_packages(["dv_processing", "numpy"]) first."""
    import dv_processing as dv
    import numpy as np

    rec = dv.io.MonoCameraRecording(str(path))
    res = rec.getEventResolution()
    time_range = rec.getTimeRange()
    parts = []
    while True:
        batch = rec.getNextEventBatch()
        if batch is None:
            break
        a = batch.numpy()
        parts.append(np.stack([a["timestamp"], a["x"], a["y"], a["polarity"]], axis=1).astype(np.int64))
    events = np.concatenate(parts) if parts else np.zeros((0, 4), dtype=np.int64)
    return events, (int(res[0]), int(res[1])), (int(time_range[0]), int(time_range[1]))
