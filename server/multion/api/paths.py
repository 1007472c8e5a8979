"""Which files a remote client may make the server read: datasets and mesh scenes.

A session config's ``dataset`` and an episode's mesh ``scene_id`` are paths on the *server's*
disk. Without a check any client could have the server open any file it can read, so a path is
accepted only when, after ``Path.resolve()`` (symlinks followed, ``..`` removed), it lies inside
the packaged datasets directory or one of ``ServerSettings.allowed_dataset_dirs``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from multion.config.datasets import DATA_DIR
from multion.scenes.registry import is_mesh_scene
from multion_client.errors import PathNotAllowed


def allowed_roots(extra: Iterable[Path]) -> tuple[Path, ...]:
    """The packaged datasets directory plus ``extra``, each resolved once."""
    return (DATA_DIR.resolve(), *(Path(p).expanduser().resolve() for p in extra))


def check_path(path: str, roots: Sequence[Path], what: str) -> str:
    """``path`` resolved, if it lies inside one of ``roots``; :class:`PathNotAllowed` otherwise.

    The resolved form is what the worker opens, so a ``..`` or a symlink cannot point elsewhere
    between the check and the read.
    """
    try:
        resolved = Path(path).expanduser().resolve()
    except (OSError, RuntimeError, ValueError):  # symlink loops, NUL bytes
        raise PathNotAllowed(f"{what} {path!r} is not a usable path") from None
    if any(resolved.is_relative_to(root) for root in roots):
        return str(resolved)
    # The message names the client's value only: the server's directories are its own business.
    raise PathNotAllowed(
        f"{what} {path!r} is outside the directories this server may read (its packaged "
        "datasets and those its operator allowed with `multion serve --dataset-dir DIR` or "
        "MULTION_ALLOWED_DATASET_DIRS)"
    )


def checked_config(config: Mapping[str, Any], roots: Sequence[Path]) -> dict[str, Any]:
    """A session config with its ``dataset`` and inline episodes' mesh scenes checked.

    Call after the config was validated: fields are known to have the right types.
    """
    checked = dict(config)
    if isinstance(checked.get("dataset"), str):
        checked["dataset"] = check_path(checked["dataset"], roots, "dataset")
    episodes = checked.get("episodes")
    if isinstance(episodes, list):
        checked["episodes"] = [checked_episode(e, roots) for e in episodes]
    return checked


def checked_episode(episode: Any, roots: Sequence[Path]) -> Any:
    """``episode`` unchanged once a mesh ``scene_id`` in it is checked (procedural ids pass).

    The scene id is not rewritten: it is the episode's identity, echoed back in infos.
    """
    if isinstance(episode, Mapping):  # anything else is not an episode: the worker says so
        scene = episode.get("scene_id")
        if isinstance(scene, str) and is_mesh_scene(scene):
            check_path(scene, roots, "mesh scene")
    return episode


def checked_options(options: list[Any], roots: Sequence[Path]) -> list[Any]:
    """Reset options with any inline ``episode`` checked like :func:`checked_episode`."""
    return [
        {**o, "episode": checked_episode(o["episode"], roots)}
        if isinstance(o, Mapping) and "episode" in o
        else o
        for o in options
    ]
