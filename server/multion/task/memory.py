"""An upper bound on the memory one environment may use, known from its config alone.

A server checks a session's estimate against its workers' memory before any worker allocates,
so a client cannot make a simulator worker grow without bound. The bound covers the worst
scene the session could reach (a client may reset into any scene of at most
``MAX_SCENE_SIDE_M`` metres a side), so it is loose for small scenes and tight for the big
costs: images, navigable-grid fields and map crops. The coefficients were measured on this
project's simulator (``multion bench --only memory`` prints measured against estimated).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from multion.config.task import EnvConfig
from multion.scenes.registry import MAX_ROOM_SIDE_M
from multion.task.sensors import sensors_working_bytes

MiB = 2**20

ENV_BASE_BYTES = 64 * MiB
"""A PyBullet world with a house in it, the env's objects and their buffers (measured: ~32 MiB)."""
BYTES_PER_PIXEL = 96
"""Per camera pixel: PyBullet's RGBA, depth and segmentation buffers, the float64 depth
conversion and the observation arrays (measured: ~50 held, more while rendering)."""
BYTES_PER_GRID_CELL_AND_FIELD = 8
"""A float64 distance field (one per goal, plus the fast-marching scratch) per grid cell."""
SCRATCH_FIELDS = 4
EGL_WORLD_BYTES = 768 * MiB
"""A world rendered through PyBullet's EGL plugin (measured with Mesa: ~360 MiB resident, ~720
MiB of address space); counted for ``egl``."""
GL_CONTEXT_BYTES = 384 * MiB
"""The one OpenGL context of a process rendering with the project's renderer (``gl``, and
``auto``, which picks gl or tiny), counted once per worker process (:class:`ProcessShare`).
Measured with Mesa's llvmpipe, gl minus tiny at 36², 128² and 256² alike: ~99 MiB resident and
~365 MiB of address space (workers are limited in address space) for the context drawing in
the calling thread (``LP_NUM_THREADS=0``), more per rendering thread (:data:`GL_THREAD_BYTES`),
then ~8 MiB per env (:data:`GL_ENV_BYTES`)."""
GL_THREAD_BYTES = 160 * MiB
"""Each of Mesa's llvmpipe rendering threads (``LP_NUM_THREADS``) adds to a context: measured
+144 MiB of address space apiece (a thread's stack and malloc arenas), no resident memory to
speak of (:func:`llvmpipe_threads`)."""
GL_ENV_BYTES = 16 * MiB
"""What each env adds to the context: its scene's buffers on the GL side (measured ~8 MiB)."""
GL_RENDERERS = ("gl", "auto")
RENDERER_ENV_BYTES = {"tiny": 0, "gl": GL_ENV_BYTES, "auto": GL_ENV_BYTES, "egl": EGL_WORLD_BYTES}
MAX_SCENE_SIDE_M = MAX_ROOM_SIDE_M
"""The largest scene side a session may reach (procedural houses are smaller)."""


def estimate_env_bytes(config: EnvConfig) -> int:
    """An upper bound on the memory one environment of ``config`` holds at its peak, besides
    what it shares with the other envs of its process (:func:`process_share`)."""
    pixels = config.camera.width * config.camera.height
    side_cells = MAX_SCENE_SIDE_M / config.navgrid.cell_size + 1
    fields = config.task.num_goals + config.task.num_distractors + SCRATCH_FIELDS
    grid = int(side_cells**2) * fields * BYTES_PER_GRID_CELL_AND_FIELD
    sensors = sensors_working_bytes(config)  # the oracle map's crop, when a sensor reads it
    renderer = RENDERER_ENV_BYTES[config.camera.renderer]
    return ENV_BASE_BYTES + pixels * BYTES_PER_PIXEL + grid + sensors + renderer


def goal_sites_bytes(config: EnvConfig) -> int:
    """The goal sites' field cache (:mod:`multion.task.goal_sites`): its budget, where train
    episodes are drawn from sites; nothing where episodes come from a dataset. One cache serves
    every env of a process, so it is counted once per process, not per env."""
    drawn_from_sites = (
        config.split == "train" and config.dataset is None and config.task.train_sampler == "sites"
    )
    return config.task.goal_site_cache_mib * MiB if drawn_from_sites else 0


@dataclass(frozen=True)
class ProcessShare:
    """What the environments of one worker process share, reserved once per process."""

    site_cache: int = 0
    """The goal-site field cache: the largest budget of the envs drawing from it."""
    gl_context: int = 0
    """The process's one OpenGL context."""

    @property
    def total(self) -> int:
        return self.site_cache + self.gl_context

    def merged(self, other: ProcessShare) -> ProcessShare:
        """What a process holding the envs of both needs (one cache, sized for the largest
        budget, and one context)."""
        return ProcessShare(
            max(self.site_cache, other.site_cache), max(self.gl_context, other.gl_context)
        )

    def describe(self) -> str:
        """The parts, for messages: "800 MiB for the goal-site field cache (…) and …"."""
        parts = []
        if self.site_cache:
            parts.append(f"{mib(self.site_cache)} MiB for the goal-site field cache "
                         "(task.goal_site_cache_mib)")  # fmt: skip
        if self.gl_context:
            parts.append(f"{mib(self.gl_context)} MiB for the OpenGL context (camera.renderer)")
        return " and ".join(parts)


def llvmpipe_threads() -> int:
    """Mesa's rendering threads per context in a worker: ``LP_NUM_THREADS`` where the server's
    environment sets it (workers inherit it), else 1, the most the project sets itself (the gl
    renderer sets 0, PyBullet's EGL plugin 1, whichever a process opens first)."""
    value = os.environ.get("LP_NUM_THREADS", "1")
    return max(0, int(value)) if value.strip().isdigit() else 1


def process_share(config: EnvConfig) -> ProcessShare:
    """What an env of ``config`` shares with the other envs of its process."""
    context = 0
    if config.camera.renderer in GL_RENDERERS:
        context = GL_CONTEXT_BYTES + llvmpipe_threads() * GL_THREAD_BYTES
    return ProcessShare(site_cache=goal_sites_bytes(config), gl_context=context)


def estimate_process_bytes(config: EnvConfig, num_envs: int) -> int:
    """An upper bound on what ``num_envs`` environments of ``config`` in one process hold:
    each env's own memory and, once, what they share."""
    return num_envs * estimate_env_bytes(config) + process_share(config).total


def mib(size: int) -> int:
    """``size`` bytes in MiB, rounded up (for messages)."""
    return -(-size // MiB)
