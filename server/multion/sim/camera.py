"""The agent's RGB-D camera: PyBullet's CPU renderer seen from the agent's eye."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p

from multion.ranges import bounded, check_fields, require


@dataclass(frozen=True)
class CameraConfig:
    """The RGB-D sensor (SPEC §2; the reference code's values)."""

    width: int = bounded(256, 1, 1024)
    """Image width in pixels (1024 bounds an image's memory, about 100 bytes a pixel)."""
    height: int = bounded(256, 1, 1024)
    hfov_deg: float = bounded(79.0, 1.0, 170.0)
    """Horizontal field of view, degrees."""
    sensor_height: float = bounded(0.88, 0.05, 3.0)
    """Camera height above the floor, metres."""
    min_depth: float = bounded(0.5, 0.0, 100.0)
    max_depth: float = bounded(5.0, 0.0, 100.0, low_open=True)
    normalize_depth: bool = True
    """Depth in metres clipped to ``[min_depth, max_depth]``, then mapped to ``[0, 1]``."""
    near: float = bounded(0.02, 0.001, 1.0)
    """Near clipping plane, metres."""
    far: float = bounded(60.0, 1.0, 1000.0)
    """Far clipping plane, metres."""

    def __post_init__(self) -> None:
        check_fields(self, "camera")
        require(
            self.min_depth < self.max_depth,
            f"camera.min_depth ({self.min_depth}) must be below camera.max_depth "
            f"({self.max_depth})",
        )
        require(
            self.near < self.far, f"camera.near ({self.near}) must be below camera.far ({self.far})"
        )

    @property
    def vfov_deg(self) -> float:
        half = math.radians(self.hfov_deg) / 2
        return math.degrees(2 * math.atan(math.tan(half) * self.height / self.width))


@dataclass(frozen=True)
class CameraImage:
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W, 1) float32, processed as configured
    segmentation: np.ndarray | None  # (H, W) int32 body ids, -1 for background


class Camera:
    """Renders from a pose; the projection is computed once."""

    def __init__(
        self, config: CameraConfig, client: int, lighting: tuple[float, float] = (0.6, 0.4)
    ) -> None:
        self.config = config
        self.client = client
        self.ambient, self.diffuse = lighting
        self.projection = p.computeProjectionMatrixFOV(
            fov=config.vfov_deg,
            aspect=config.width / config.height,
            nearVal=config.near,
            farVal=config.far,
        )

    def render(
        self, x: float, y: float, yaw: float, floor_z: float, segmentation: bool = False
    ) -> CameraImage:
        c = self.config
        eye = (x, y, floor_z + c.sensor_height)
        target = (x + math.cos(yaw), y + math.sin(yaw), eye[2])
        view = p.computeViewMatrix(eye, target, (0.0, 0.0, 1.0))
        flags = 0 if segmentation else p.ER_NO_SEGMENTATION_MASK
        _, _, rgba, zbuffer, seg = p.getCameraImage(
            c.width,
            c.height,
            view,
            self.projection,
            shadow=0,
            lightAmbientCoeff=self.ambient,
            lightDiffuseCoeff=self.diffuse,
            lightSpecularCoeff=0.0,
            renderer=p.ER_TINY_RENDERER,
            flags=flags,
            physicsClientId=self.client,
        )
        rgb = np.ascontiguousarray(np.reshape(rgba, (c.height, c.width, 4))[:, :, :3])
        depth = self.process_depth(np.reshape(zbuffer, (c.height, c.width)))
        seg_array = np.reshape(seg, (c.height, c.width)).astype(np.int32) if segmentation else None
        return CameraImage(rgb=rgb, depth=depth, segmentation=seg_array)

    def process_depth(self, zbuffer: np.ndarray) -> np.ndarray:
        """OpenGL depth buffer → planar depth in metres → clipped (and normalised) float32."""
        c = self.config
        metres = c.far * c.near / (c.far - (c.far - c.near) * zbuffer.astype(np.float64))
        metres = np.clip(metres, c.min_depth, c.max_depth)
        if c.normalize_depth:
            metres = (metres - c.min_depth) / (c.max_depth - c.min_depth)
        return metres.astype(np.float32)[:, :, None]
