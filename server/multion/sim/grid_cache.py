"""A disk cache of navigable grids: a house's grid takes seconds of ray casts, loading it
milliseconds.

One ``.npz`` file per (scene, grid settings, scene generator version, grid algorithm version),
named by a hash of that key, which the file also stores and is checked on reading. Files are
written atomically (temporary file, then rename), so processes building the same scene at once
never see half a file; an unreadable or mismatched file is rebuilt, with a warning.

Where: ``$MULTION_NAVGRID_CACHE`` if set (``off`` disables the cache), else
``$XDG_CACHE_HOME/multion/navgrids``, else ``~/.cache/multion/navgrids``. Safe to delete.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
import warnings
from pathlib import Path

import numpy as np

from multion.common.files import replacing
from multion.config.sim import NavGridConfig
from multion.scenes.registry import (
    GENERATOR_VERSION,
    SIZED_HOUSE_REVISION,
    is_mesh_scene,
    is_sized_house,
)
from multion.sim.navgrid import NAVGRID_VERSION, NavGrid

CACHE_ENV = "MULTION_NAVGRID_CACHE"
"""Environment variable: the cache directory, or ``off`` to disable the cache."""
DISABLED = ("off", "0", "false", "no", "none")
_ARRAYS = ("inside", "free", "navigable", "view_blocked")


class NavGridCacheError(ValueError):
    """A cache file that cannot be used (unreadable, or written for another key)."""


def cache_dir() -> Path | None:
    """The cache directory, or None when the cache is disabled."""
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        if value.strip().lower() in DISABLED or not value.strip():
            return None
        return Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "multion" / "navgrids"


def cache_key(scene_id: str, config: NavGridConfig) -> str:
    """The key a cached grid must match: everything its cells depend on, as canonical JSON.
    Mesh scenes are identified by their resolved path, size and modification time."""
    scene: dict[str, object] = {"id": scene_id}
    if is_sized_house(scene_id):  # changed alone; the default houses' keys stay as they were
        scene["sized_revision"] = SIZED_HOUSE_REVISION
    if is_mesh_scene(scene_id):
        path = Path(scene_id).resolve()
        stat = path.stat()
        scene = {"mesh": str(path), "bytes": stat.st_size, "mtime_ns": stat.st_mtime_ns}
    key = {
        "scene": scene,
        "navgrid": dataclasses.asdict(config),
        "generator_version": GENERATOR_VERSION,
        "navgrid_version": NAVGRID_VERSION,
    }
    return json.dumps(key, sort_keys=True)


def cache_path(directory: Path, scene_id: str, key: str) -> Path:
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(scene_id).name)[:60]
    return directory / f"{stem}-{hashlib.sha256(key.encode()).hexdigest()[:20]}.npz"


def save(path: Path, grid: NavGrid, key: str) -> None:
    """Write ``grid`` to ``path`` atomically (temporary file in the same directory, rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as temporary, temporary.open("wb") as stream:
        np.savez_compressed(
            stream,
            key=np.array(key),
            origin=np.asarray(grid.origin, dtype=np.float64),
            cell_size=np.float64(grid.cell_size),
            floor_z=np.float64(grid.floor_z),
            **{name: getattr(grid, name) for name in _ARRAYS},
        )


def load(path: Path, key: str) -> NavGrid:
    """The grid stored in ``path`` for ``key``; :class:`NavGridCacheError` if it is unusable."""
    try:
        with np.load(path, allow_pickle=False) as data:
            stored_key = str(data["key"])
            arrays = {name: np.asarray(data[name]) for name in _ARRAYS}
            origin = [float(v) for v in data["origin"]]
            cell_size, floor_z = float(data["cell_size"]), float(data["floor_z"])
    except Exception as error:  # zip, pickle, key and value errors: all mean "rebuild"
        raise NavGridCacheError(f"{path}: unreadable navgrid cache file ({error})") from None
    if stored_key != key:
        raise NavGridCacheError(f"{path}: written for another scene or settings")
    shapes = {a.shape for a in arrays.values()}
    if len(shapes) != 1 or len(origin) != 2 or any(a.dtype != bool for a in arrays.values()):
        raise NavGridCacheError(f"{path}: inconsistent navgrid arrays")
    return NavGrid((origin[0], origin[1]), cell_size, floor_z, **arrays)


def cached_grid(scene_id: str, config: NavGridConfig) -> tuple[NavGrid | None, Path | None, str]:
    """(the cached grid or None, the file it lives or should live in or None, its key)."""
    directory = cache_dir()
    key = cache_key(scene_id, config)
    if directory is None:
        return None, None, key
    path = cache_path(directory, scene_id, key)
    if not path.is_file():
        return None, path, key
    try:
        return load(path, key), path, key
    except NavGridCacheError as error:
        warnings.warn(f"{error}; rebuilding it", stacklevel=2)
        return None, path, key


def store(path: Path | None, grid: NavGrid, key: str) -> None:
    """Save a freshly built grid; a cache directory that cannot be written is only a warning."""
    if path is None:
        return
    try:
        save(path, grid, key)
    except OSError as error:
        warnings.warn(
            f"navgrid cache not written ({error}); set {CACHE_ENV} to a writable directory "
            f"or to 'off'",
            stacklevel=2,
        )
