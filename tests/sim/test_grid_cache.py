"""The disk cache of navigable grids: a hit equals a fresh build, keys separate settings and
versions, a corrupt file is rebuilt with a warning, and the cache can be turned off."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from multion.config.sim import NavGridConfig
from multion.sim import grid_cache, simulator
from multion.sim.simulator import Simulator

ROOM = "room-6x4"


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty cache directory, and an empty in-process grid cache."""
    monkeypatch.setenv(grid_cache.CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(simulator, "_GRID_CACHE", type(simulator._GRID_CACHE)())
    return tmp_path


def _forbid_building(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*_: object) -> None:
        raise AssertionError("the grid was rebuilt instead of read from the cache")

    monkeypatch.setattr(simulator, "build_navgrid", refuse)


def _assert_same(a, b) -> None:
    assert a.origin == b.origin and a.cell_size == b.cell_size and a.floor_z == b.floor_z
    for name in ("inside", "free", "navigable", "view_blocked"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_a_cached_grid_equals_the_built_one(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    built = Simulator().load_scene(ROOM)
    files = list(cache.glob("*.npz"))
    assert len(files) == 1 and files[0].name.startswith(ROOM)
    simulator._GRID_CACHE.clear()  # a new process: only the disk remembers
    _forbid_building(monkeypatch)
    _assert_same(Simulator().load_scene(ROOM), built)


def test_keys_separate_settings_and_versions(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    base = grid_cache.cache_key(ROOM, NavGridConfig())
    assert grid_cache.cache_key(ROOM, NavGridConfig(cell_size=0.1)) != base
    assert grid_cache.cache_key("room-6x5", NavGridConfig()) != base
    monkeypatch.setattr(grid_cache, "GENERATOR_VERSION", grid_cache.GENERATOR_VERSION + 1)
    bumped = grid_cache.cache_key(ROOM, NavGridConfig())
    assert bumped != base
    assert grid_cache.cache_path(cache, ROOM, bumped) != grid_cache.cache_path(cache, ROOM, base)
    # a file written for one key is refused for another
    Simulator().load_scene(ROOM)
    (path,) = cache.glob("*.npz")
    with pytest.raises(grid_cache.NavGridCacheError, match="another"):
        grid_cache.load(path, base)


def test_a_corrupt_file_is_rebuilt_with_a_warning(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    built = Simulator().load_scene(ROOM)
    (path,) = cache.glob("*.npz")
    path.write_bytes(b"not a zip file at all")
    simulator._GRID_CACHE.clear()
    with pytest.warns(UserWarning, match="unreadable navgrid cache file"):
        rebuilt = Simulator().load_scene(ROOM)
    _assert_same(rebuilt, built)
    simulator._GRID_CACHE.clear()
    _forbid_building(monkeypatch)  # the rebuilt grid was written back, whole
    _assert_same(Simulator().load_scene(ROOM), built)
    assert not list(cache.glob(".*"))  # no temporary files left behind


def test_the_cache_can_be_turned_off(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(grid_cache.CACHE_ENV, "off")
    assert grid_cache.cache_dir() is None
    Simulator().load_scene(ROOM)
    assert not list(cache.iterdir())


def test_the_default_directory_follows_xdg(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(grid_cache.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert grid_cache.cache_dir() == tmp_path / "multion" / "navgrids"


def test_an_unwritable_directory_only_warns(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = cache / "file"
    blocker.write_text("a file where the directory should be")
    monkeypatch.setenv(grid_cache.CACHE_ENV, str(blocker / "navgrids"))
    with pytest.warns(UserWarning, match="navgrid cache not written"):
        grid = Simulator().load_scene(ROOM)
    assert grid.navigable.any()
