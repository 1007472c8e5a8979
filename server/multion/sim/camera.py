"""The agent's RGB-D camera: PyBullet's CPU renderer seen from the agent's eye."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p


@dataclass(frozen=True)
class CameraConfig:
    """The RGB-D sensor (SPEC §2; the reference code's values)."""

    width: int = 256
    height: int = 256
    hfov_deg: float = 79.0
    """Horizontal field of view."""
    sensor_height: float = 0.88
    """Camera height above the floor, metres."""
    min_depth: float = 0.5
    max_depth: float = 5.0
    normalize_depth: bool = True
    """Depth in metres clipped to ``[min_depth, max_depth]``, then mapped to ``[0, 1]``."""
    near: float = 0.02
    far: float = 60.0

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
