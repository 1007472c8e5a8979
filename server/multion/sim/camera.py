"""The agent's RGB-D camera: PyBullet's TinyRenderer, the project's OpenGL renderer, or PyBullet's
EGL plugin.

``tiny`` is PyBullet's software rasteriser: available everywhere, the same pixels on every
machine, the reference. ``gl`` is the project's own OpenGL 3.3 renderer of the same world
(:mod:`multion.sim.gl`: moderngl, a headless EGL context; NVIDIA's driver on a GPU, Mesa's
llvmpipe on a CPU), matched to TinyRenderer's pictures. ``egl`` is PyBullet's ``eglRenderer``
plugin (``ER_BULLET_HARDWARE_OPENGL``). ``auto`` picks ``gl`` when its context opens and
TinyRenderer otherwise.

The EGL plugin must be loaded into a physics client before any body is created (bodies
created earlier are invisible to it), so :func:`attach_renderer` is called by the world right
after it connects; each world (one per loaded scene) holds one plugin. Reusing one client
across scenes with ``resetSimulation`` would save the plugin's start-up, but PyBullet's EGL
plugin loses the connection when bodies are created after a reset (PyBullet 3.2.7).
"""

from __future__ import annotations

import contextlib
import importlib.util
import math
import os
from dataclasses import dataclass

import numpy as np

from multion.config.errors import UsageError
from multion.config.sim import RENDERERS, CameraConfig
from multion.sim.bullet import c_output_silenced
from multion.sim.bullet import pybullet as p
from multion.sim.gl.context import (
    EGL_PACKAGES,
    gl_unavailable_reason,
    gl_unavailable_reason_in_child,
)
from multion.sim.gl.renderer import GLRenderer, shifted_projection
from multion_client.errors import InvalidConfig

CAMERA_RENDERERS = ("tiny", "gl", "egl")
"""What a camera renders with once ``auto`` is resolved."""


class RendererUnavailableError(UsageError, InvalidConfig, ValueError):
    """``camera.renderer`` names ``gl`` or ``egl`` on a machine where it cannot run."""


@dataclass(frozen=True)
class CameraImage:
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W, 1) float32, processed as configured
    segmentation: np.ndarray | None  # (H, W) int32 body ids, -1 for background


class Camera:
    """Renders from a pose with the world's renderer (``tiny``, ``gl`` or ``egl``, see
    :func:`attach_renderer`); the projection is computed once. ``gl`` needs the world's
    :class:`GLRenderer` (``PyBulletWorld.gl``)."""

    def __init__(
        self,
        config: CameraConfig,
        client: int,
        renderer: str = "tiny",
        lighting: tuple[float, float] = (0.6, 0.4),
        gl: GLRenderer | None = None,
    ) -> None:
        if renderer not in CAMERA_RENDERERS:
            raise ValueError(f"a camera renders with tiny, gl or egl, not {renderer!r}")
        if renderer == "gl" and gl is None:
            raise ValueError("a gl camera needs the world's GL scene (PyBulletWorld.gl)")
        self.config = config
        self.gl = gl
        self.client = client
        self.renderer = renderer
        self._flag = p.ER_BULLET_HARDWARE_OPENGL if renderer == "egl" else p.ER_TINY_RENDERER
        self.ambient, self.diffuse = lighting
        self.egl_light_position = EGL_LIGHT_POSITION
        """Where the EGL plugin's light is placed (benches set ``EGL_PLUGIN_LIGHT`` to time
        the plugin's shadow pass)."""
        self.projection = p.computeProjectionMatrixFOV(
            fov=config.vfov_deg,
            aspect=config.width / config.height,
            nearVal=config.near,
            farVal=config.far,
        )
        self.gl_projection = shifted_projection(self.projection, config.width, config.height)
        if renderer == "egl":
            self.projection = _shift_image(
                self.projection,
                EGL_PIXEL_SHIFT[0] / config.width,
                EGL_PIXEL_SHIFT[1] / config.height,
            )

    def render(
        self, x: float, y: float, yaw: float, floor_z: float, segmentation: bool = False
    ) -> CameraImage:
        c = self.config
        eye = (x, y, floor_z + c.sensor_height)
        target = (x + math.cos(yaw), y + math.sin(yaw), eye[2])
        view = p.computeViewMatrix(eye, target, (0.0, 0.0, 1.0))
        if self.gl is not None and self.renderer == "gl":
            image = self.gl.render(
                c.width, c.height, view, self.gl_projection, (self.ambient, self.diffuse), c.far
            )
            return CameraImage(
                rgb=image.rgb,
                depth=self.finish_depth(image.depth),
                segmentation=image.segmentation if segmentation else None,
            )
        flags = 0 if segmentation else p.ER_NO_SEGMENTATION_MASK
        egl = self.renderer == "egl"
        # the EGL plugin prints its OpenGL vendor ("ven = …") when it uploads new bodies
        with c_output_silenced() if egl else contextlib.nullcontext():
            # TinyRenderer's call stays exactly as it was
            light = {"lightDirection": self.egl_light_position} if egl else {}
            _, _, rgba, zbuffer, seg = p.getCameraImage(
                c.width,
                c.height,
                view,
                self.projection,
                shadow=0,
                lightAmbientCoeff=self.ambient,
                lightDiffuseCoeff=self.diffuse,
                lightSpecularCoeff=0.0,
                renderer=self._flag,
                flags=flags,
                physicsClientId=self.client,
                **light,
            )
        rgb = np.ascontiguousarray(np.reshape(rgba, (c.height, c.width, 4))[:, :, :3])
        depth = self.process_depth(np.reshape(zbuffer, (c.height, c.width)))
        seg_array = np.reshape(seg, (c.height, c.width)).astype(np.int32) if segmentation else None
        return CameraImage(rgb=rgb, depth=depth, segmentation=seg_array)

    def process_depth(self, zbuffer: np.ndarray) -> np.ndarray:
        """OpenGL depth buffer → planar depth in metres → clipped (and normalised) float32."""
        c = self.config
        metres = c.far * c.near / (c.far - (c.far - c.near) * zbuffer.astype(np.float64))
        return self.finish_depth(metres)

    def finish_depth(self, metres: np.ndarray) -> np.ndarray:
        """Planar depth in metres → clipped (and normalised) (H, W, 1) float32."""
        c = self.config
        metres = np.clip(metres, c.min_depth, c.max_depth)
        if c.normalize_depth:
            metres = (metres - c.min_depth) / (c.max_depth - c.min_depth)
        return metres.astype(np.float32)[:, :, None]


EGL_PLUGIN_LIGHT = (-5.0, -40.0, 200.0)
"""The EGL plugin's own light position, used when ``getCameraImage`` names none."""
EGL_LIGHT_POSITION = (-25.0, -200.0, 1000.0)
"""Where cameras put the EGL plugin's light: in its own direction, five times as far. The
plugin renders a shadow map from its light every frame, whatever ``shadow`` says, with an
orthographic camera that sees 1–300 m from the light, and darkens what that map shadows;
TinyRenderer, asked for ``shadow=0`` like the plugin, draws no shadows. From 1,020 m the map
sees nothing: no shadows (only pixels the map shadowed change, and only get lighter), and
about 10 ms less per image of a house with Mesa on one thread (``docs/training-speed.md``)."""

EGL_PIXEL_SHIFT = (1.0, 1.0)
"""TinyRenderer samples each pixel half a pixel off OpenGL's pixel centres, in x and in y.
EGL's projection is shifted by (x, y) half-pixels (in NDC units of 2 / size) so that both
renderers sample the same rays: median depth differences at 64² fall from 0.003–0.01 to 0.0002
(of the 4.5 m range)."""


def _shift_image(projection: tuple[float, ...], dx: float, dy: float) -> tuple[float, ...]:
    """A column-major OpenGL projection whose image moves by (dx, dy) in NDC."""
    matrix = list(projection)
    for column in range(4):
        matrix[column * 4 + 0] += dx * matrix[column * 4 + 3]
        matrix[column * 4 + 1] += dy * matrix[column * 4 + 3]
    return tuple(matrix)


# ---------------------------------------------------------------------- renderer plugins
_egl_failed = False
"""Set once the plugin failed to load in this process: ``auto`` then stops trying."""
_egl_loaded = False
"""Set once the plugin loaded in this process (``resolve_renderer`` need not probe again)."""


def attach_renderer(client: int, requested: str) -> str:
    """Prepare a fresh physics client (no bodies yet) for ``requested`` ("tiny", "gl", "egl"
    or "auto"); returns the renderer its camera must use, "tiny", "gl" or "egl"."""
    if requested not in RENDERERS:
        raise ValueError(f"renderer must be one of {', '.join(RENDERERS)}, got {requested!r}")
    if requested == "tiny":
        return "tiny"
    if requested in ("gl", "auto"):
        reason = gl_unavailable_reason()
        if reason is None:
            return "gl"
        if requested == "gl":
            raise RendererUnavailableError(reason + " (or camera.renderer 'auto')")
        return "tiny"
    if _load_egl(client):
        return "egl"
    raise RendererUnavailableError(
        "camera.renderer 'egl': PyBullet's EGL plugin did not load. On a GPU machine install "
        f"NVIDIA's driver; without a GPU install Mesa's EGL (Debian/Ubuntu: apt-get install "
        f"{EGL_PACKAGES}). Or use camera.renderer 'auto', 'gl' or 'tiny'."
    )


def resolve_renderer(requested: str) -> str:
    """The renderer ``requested`` gives in this process: "auto" is "gl" when an OpenGL
    context opens (tried once per process), else "tiny"."""
    if requested != "auto":
        return requested
    return "gl" if gl_unavailable_reason() is None else "tiny"


def why_not_gl() -> str | None:
    """One line saying why ``auto`` falls back to TinyRenderer here, or None."""
    return gl_unavailable_reason()


def auto_renderer_elsewhere() -> tuple[str, str | None]:
    """What ``auto`` resolves to on this machine and why not gl (or None), found by a child
    process: this one opens no OpenGL context unless an env of its own renders with gl."""
    reason = gl_unavailable_reason_in_child()
    return ("gl" if reason is None else "tiny"), reason


def egl_plugin_loads() -> bool:
    """Whether PyBullet's EGL plugin loads in this process (probed once, with a throwaway
    client)."""
    if _egl_failed or _egl_loaded:
        return _egl_loaded
    client = p.connect(p.DIRECT)
    try:
        return _load_egl(client)
    finally:
        with c_output_silenced():  # the EGL plugin says goodbye
            p.disconnect(physicsClientId=client)


def egl_plugin_path() -> str | None:
    """The eglRenderer extension shipped with pybullet, or None."""
    spec = importlib.util.find_spec("eglRenderer")
    return spec.origin if spec is not None else None


def _load_egl(client: int) -> bool:
    global _egl_failed, _egl_loaded
    if _egl_failed:
        return False
    path = egl_plugin_path()
    plugin = -1
    # Mesa's llvmpipe starts one rendering thread per core by default; simulator processes
    # already share the cores, so each renders on one thread (set LP_NUM_THREADS to override)
    os.environ.setdefault("LP_NUM_THREADS", "1")
    if path is not None:
        with c_output_silenced():  # the plugin prints its device, OpenGL vendor and version
            plugin = p.loadPlugin(path, "_eglRendererPlugin", physicsClientId=client)
    if plugin < 0:
        _egl_failed = True
        return False
    _egl_loaded = True
    return True
