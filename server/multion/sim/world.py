"""The PyBullet side of the simulator: one DIRECT client holding a static scene and the goal objects.

The world only builds geometry and answers geometric queries (ray casts, camera images). Motion,
rules and metrics live in the task; nothing here knows about episodes or networks.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from functools import partial
from pathlib import Path

import numpy as np

from multion.common.files import replacing
from multion.config.errors import UsageError
from multion.scenes.layout import Box, SceneLayout
from multion.scenes.textures import SIZE_STEP, texture_file
from multion.sim.bullet import c_output_silenced
from multion.sim.bullet import pybullet as p
from multion.sim.camera import attach_renderer, resolve_renderer
from multion.sim.gl.renderer import GLRenderer
from multion.sim.goal_objects import MODELS, body_bounds, scaled_urdf
from multion.sim.goal_shapes import goal_mesh_file
from multion.sim.merged_visual import merged_visual
from multion_client.constants import OBJECT_CATEGORIES
from multion_client.errors import InvalidConfig

# pybullet refuses ray batches above this size
RAY_BATCH_LIMIT = 16_384
MESH_SUFFIXES = (".obj", ".glb", ".gltf", ".ply")
HIDDEN_POSITION = (0.0, 0.0, -100.0)
DEFAULT_LIGHTING = (0.6, 0.4)  # (ambient, diffuse): rooms, meshes, houses that say nothing


class MeshSceneError(UsageError, InvalidConfig, ValueError):
    """A mesh scene file that cannot be used (its format, or a file PyBullet or trimesh cannot
    read): the fault of whoever named it, not of the simulator."""


class PyBulletWorld:
    """A PyBullet physics client with one scene loaded.

    Build it with :meth:`from_layout` (procedural scenes) or :meth:`from_mesh` (scans). Goal
    cylinders are visual-only bodies: they are rendered but neither block the agent nor rays.
    """

    def __init__(self, renderer: str = "tiny", unseen_boxes: Sequence[Box] = ()) -> None:
        """``unseen_boxes`` become collision-only bodies created before the renderer plugin
        loads, which makes them invisible to it (see :meth:`from_layout`)."""
        self.client = p.connect(p.DIRECT)
        self.scene_bodies: list[int] = []
        try:
            for box in unseen_boxes:
                self.scene_bodies.append(self._box_body(box, visual=False))
            # a renderer plugin must be in place before the first body it should draw
            self.renderer = attach_renderer(self.client, renderer)
        except BaseException:
            p.disconnect(physicsClientId=self.client)
            raise
        """The renderer cameras of this world use: "tiny", "gl" or "egl" (see ``sim.camera``)."""
        self.gl: GLRenderer | None = None
        """The GL mirror of this world's bodies (renderer "gl"), made by :meth:`mirror_in_gl`."""
        self.body_textures: dict[int, Path] = {}
        """The image file each textured body was given (PyBullet does not report it back)."""
        self.visual_bodies: list[int] = []
        """Visual-only bodies of the scene (the merged mesh under EGL), drawn, never hit."""
        self._goal_bodies: dict[Hashable, list[int]] = {}
        self._object_offsets: dict[str, tuple[float, ...]] = {}
        self._goal_in_use: list[int] = []
        self._texture_paths: dict[int, Path] = {}
        self.lighting: tuple[float, float] = DEFAULT_LIGHTING
        """(ambient, diffuse) light coefficients of the camera in this scene."""

    # ------------------------------------------------------------------ building
    @classmethod
    def from_layout(
        cls, layout: SceneLayout, renderer: str = "tiny", merge: bool = True
    ) -> PyBulletWorld:
        """One static body per box. With EGL (and ``merge``) the boxes are drawn as one merged
        mesh instead (:mod:`multion.sim.merged_visual`): the per-box bodies keep their
        collision shapes but are created before the plugin, so it draws one body, not
        hundreds. TinyRenderer draws the per-box bodies, exactly as before; ``merge=False``
        gives EGL the per-box bodies too (benches and tests compare the two)."""
        merge = merge and bool(layout.boxes) and resolve_renderer(renderer) == "egl"
        world = cls(renderer, unseen_boxes=layout.boxes if merge else ())
        if "lighting" in layout.metadata:  # houses vary their light a little (issue 12)
            ambient, diffuse = (float(v) for v in layout.metadata["lighting"].split(","))
            world.lighting = (ambient, diffuse)
        if merge:
            try:
                world._add_merged_visual(layout.boxes)
            except BaseException:
                world.close()
                raise
            return world
        textures: dict[tuple[str, float, float], int] = {}
        for box in layout.boxes:
            body = world._box_body(box, visual=True)
            if box.texture:
                world._apply_texture(body, box, textures)
            world.scene_bodies.append(body)
        world.mirror_in_gl()
        return world

    def mirror_in_gl(self) -> None:
        """With renderer "gl", build the GL scene from the bodies loaded so far (the static
        scene); bodies created later are drawn at their pose, image by image."""
        if self.renderer != "gl" or self.gl is not None:
            return
        try:
            self.gl = GLRenderer(
                self.client, (*self.scene_bodies, *self.visual_bodies), self.body_textures
            )
        except BaseException:
            self.close()
            raise

    def _box_body(self, box: Box, visual: bool) -> int:
        """A static box body with its collision shape, and its visual shape if ``visual``."""
        col = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=box.half_extents, physicsClientId=self.client
        )
        vis = -1
        if visual:
            vis = p.createVisualShape(
                p.GEOM_BOX,
                halfExtents=box.half_extents,
                rgbaColor=box.rgba,
                physicsClientId=self.client,
            )
        body: int = p.createMultiBody(
            baseMass=0,
            baseCollisionShapeIndex=col,
            baseVisualShapeIndex=vis,
            basePosition=box.center,
            physicsClientId=self.client,
        )
        return body

    def _add_merged_visual(self, boxes: Sequence[Box]) -> None:
        """One visual-only body drawing every box, its colours and textures in one atlas."""
        merged = merged_visual(tuple(boxes))
        vis = p.createVisualShape(
            p.GEOM_MESH, fileName=str(merged.mesh), physicsClientId=self.client
        )
        if vis < 0:
            raise RuntimeError(f"PyBullet could not load the merged scene mesh {merged.mesh}")
        body = p.createMultiBody(0, -1, vis, physicsClientId=self.client)
        texture = p.loadTexture(str(merged.atlas), physicsClientId=self.client)
        p.changeVisualShape(body, -1, textureUniqueId=texture, physicsClientId=self.client)
        self.visual_bodies.append(body)

    def _apply_texture(
        self, body: int, box: Box, loaded: dict[tuple[str, float, float], int]
    ) -> None:
        """Texture the box for the size of its largest face (floors: top; walls: long side)."""
        hx, hy, hz = (2 * h for h in box.half_extents)
        size = (hx, hy) if box.kind == "floor" else (max(hx, hy), hz)
        key = (box.texture, round(size[0] / SIZE_STEP), round(size[1] / SIZE_STEP))
        if key not in loaded:
            path = texture_file(box.texture, *size)
            loaded[key] = p.loadTexture(str(path), physicsClientId=self.client)
            self._texture_paths[loaded[key]] = path
        self.body_textures[body] = self._texture_paths[loaded[key]]
        p.changeVisualShape(body, -1, textureUniqueId=loaded[key], physicsClientId=self.client)

    @classmethod
    def from_mesh(cls, path: str | Path, renderer: str = "tiny") -> PyBulletWorld:
        """Load a scan (OBJ / GLB / GLTF / PLY) as one static, concave triangle mesh.

        Non-OBJ formats are converted to OBJ with trimesh first (PyBullet only reads OBJ).
        """
        path = Path(path)
        if path.suffix.lower() not in MESH_SUFFIXES:
            raise MeshSceneError(
                f"unsupported mesh format {path.suffix!r} for {path}; use one of {MESH_SUFFIXES}"
            )
        if not path.is_file():
            raise FileNotFoundError(f"mesh scene file not found: {path}")
        obj_path = path if path.suffix.lower() == ".obj" else _convert_to_obj(path)
        world = cls(renderer)
        col = p.createCollisionShape(
            p.GEOM_MESH,
            fileName=str(obj_path),
            flags=p.GEOM_FORCE_CONCAVE_TRIMESH,
            physicsClientId=world.client,
        )
        vis = p.createVisualShape(p.GEOM_MESH, fileName=str(obj_path), physicsClientId=world.client)
        if col < 0 or vis < 0:
            raise MeshSceneError(f"PyBullet could not load the mesh {path}")
        body = p.createMultiBody(0, col, vis, physicsClientId=world.client)
        world.scene_bodies.append(body)
        world.mirror_in_gl()
        return world

    def scene_draws(self) -> int:
        """Visual shapes of the scene (goals excluded) that the renderer draws, one draw each
        per image: the figure the EGL merge brings down (``multion bench --only sim``)."""
        goals = {body for bodies in self._goal_bodies.values() for body in bodies}
        scene = [b for b in (*self.scene_bodies, *self.visual_bodies) if b not in goals]
        return sum(len(p.getVisualShapeData(b, physicsClientId=self.client)) for b in scene)

    @property
    def goal_bodies_in_use(self) -> list[int]:
        """Bodies of the goals placed by the last :meth:`place_goals`, in order."""
        return list(self._goal_in_use)

    def close(self) -> None:
        if self.gl is not None:
            self.gl.close()
            self.gl = None
        if self.client >= 0:
            with c_output_silenced():  # the EGL plugin, if loaded, says goodbye
                p.disconnect(physicsClientId=self.client)
            self.client = -1

    def __del__(self) -> None:  # pragma: no cover - best effort at interpreter exit
        try:
            self.close()
        except Exception:
            pass

    # ------------------------------------------------------------------ queries
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds ``(low, high)`` of the scene geometry (goals excluded)."""
        lows, highs = [], []
        for body in self.scene_bodies:
            low, high = p.getAABB(body, physicsClientId=self.client)
            lows.append(low)
            highs.append(high)
        return np.min(lows, axis=0), np.max(highs, axis=0)

    def cast_rays(
        self, starts: np.ndarray, ends: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cast many rays; returns ``(hit, fraction, normal)`` arrays, one row per ray."""
        n = len(starts)
        hit = np.zeros(n, dtype=bool)
        fraction = np.ones(n)
        normal = np.zeros((n, 3))
        for lo in range(0, n, RAY_BATCH_LIMIT):
            hi = min(n, lo + RAY_BATCH_LIMIT)
            results = p.rayTestBatch(
                starts[lo:hi].tolist(), ends[lo:hi].tolist(), physicsClientId=self.client
            )
            for k, (body, _link, frac, _pos, nrm) in enumerate(results):
                if body >= 0:
                    hit[lo + k] = True
                    fraction[lo + k] = frac
                    normal[lo + k] = nrm
        return hit, fraction, normal

    # ------------------------------------------------------------------ goals
    def place_goals(
        self,
        goals: Sequence[tuple[tuple[float, float, float], tuple[float, float, float, float]]],
        radius: float,
        height: float,
    ) -> list[int]:
        """Show one cylinder per ``(base_position, rgba)``; hides the previous episode's goals.

        Bodies are reused across episodes (moving a body is far cheaper than creating one).
        """

        def cylinder(rgba: tuple[float, float, float, float]) -> int:
            visual = p.createVisualShape(
                p.GEOM_CYLINDER,
                radius=radius,
                length=height,
                rgbaColor=rgba,
                physicsClientId=self.client,
            )
            return self._visual_body(visual)

        return self._place(
            [
                (
                    (hash(tuple(rgba)), radius, height),
                    (x, y, z + height / 2),
                    partial(cylinder, rgba),
                )
                for (x, y, z), rgba in goals
            ]
        )

    def place_shape_goals(
        self,
        goals: Sequence[tuple[tuple[float, float, float], int]],
        size: float,
        support_height: float,
        rgba: tuple[float, float, float, float],
    ) -> list[int]:
        """Show one shape on its support per ``(base_position, shape category)`` (the
        supplement's shape goals, :mod:`multion.sim.goal_shapes`); hides the previous goals."""

        def shape(category: int) -> int:
            # from a file: the EGL plugin does not draw meshes given as vertices
            path = goal_mesh_file(category, size, support_height)
            visual = p.createVisualShape(
                p.GEOM_MESH, fileName=str(path), rgbaColor=rgba, physicsClientId=self.client
            )
            if visual < 0:
                raise RuntimeError(f"PyBullet could not load the goal mesh {path}")
            return self._visual_body(visual)

        return self._place(
            [
                (
                    ("shape", category, size, support_height, rgba),
                    position,
                    partial(shape, category),
                )
                for position, category in goals
            ]
        )

    def place_object_goals(
        self,
        goals: Sequence[tuple[tuple[float, float, float], int, float]],
        names: Sequence[str] = OBJECT_CATEGORIES,
    ) -> list[int]:
        """Show one object per ``(floor_position, category, yaw)``, category ``k`` being the
        model ``names[k]`` (:mod:`multion.sim.goal_objects`); hides the previous goals."""
        entries, turns = [], []
        for (x, y, z), category, yaw in goals:
            name = names[category]
            upright = MODELS[name].upright
            turns.append(p.getQuaternionFromEuler((upright[0], upright[1], upright[2] + yaw)))
            dx, dy, dz = self._object_offset(name)
            c, s = math.cos(yaw), math.sin(yaw)
            base = (x - (c * dx - s * dy), y - (s * dx + c * dy), z - dz)
            entries.append((("object", name), base, partial(self._load_object, name)))
        return self._place(entries, turns)

    def _visual_body(self, visual: int) -> int:
        """A static body showing ``visual`` (no collision shape: it blocks neither agent nor
        rays), parked out of sight."""
        body: int = p.createMultiBody(
            0, -1, visual, basePosition=HIDDEN_POSITION, physicsClientId=self.client
        )
        return body

    def _load_object(self, name: str) -> int:
        """A new body of object ``name``, scaled and without collisions, parked out of sight;
        records where the middle of its footprint's bottom lies from its base (PyBullet moves a
        body by its centre of mass, which the URDFs put off centre)."""
        model = MODELS[name]
        upright = p.getQuaternionFromEuler(model.upright)
        with c_output_silenced():  # URDFs without inertia make PyBullet complain
            body: int = p.loadURDF(str(scaled_urdf(model)), HIDDEN_POSITION, upright,
                              useFixedBase=True, physicsClientId=self.client)  # fmt: skip
        for link in range(-1, p.getNumJoints(body, physicsClientId=self.client)):
            p.setCollisionFilterGroupMask(body, link, 0, 0, physicsClientId=self.client)
        low, high = body_bounds(body, self.client)
        base = np.asarray(p.getBasePositionAndOrientation(body, physicsClientId=self.client)[0])
        bottom = np.array([(low[0] + high[0]) / 2, (low[1] + high[1]) / 2, low[2]])
        self._object_offsets[name] = tuple(float(v) for v in bottom - base)
        return body

    def _object_offset(self, name: str) -> tuple[float, ...]:
        """The bottom centre of object ``name`` from its base, upright at yaw 0."""
        if name not in self._object_offsets:  # measured on a body kept for the first goal
            self._goal_bodies.setdefault(("object", name), []).append(self._load_object(name))
        return self._object_offsets[name]

    def _place(
        self,
        goals: Sequence[tuple[Hashable, tuple[float, float, float], Callable[[], int]]],
        orientations: Sequence[tuple[float, float, float, float]] | None = None,
    ) -> list[int]:
        """Move one body per ``(key, position, make_body)`` to ``position``, reusing an idle
        body of the same ``key`` or creating one with ``make_body()``; the bodies of the
        previous call that are not reused are hidden. ``orientations``: one quaternion per goal
        (default upright)."""
        for body in self._goal_in_use:
            p.resetBasePositionAndOrientation(
                body, HIDDEN_POSITION, (0, 0, 0, 1), physicsClientId=self.client
            )
        free = {key: list(bodies) for key, bodies in self._goal_bodies.items()}
        used: list[int] = []
        turns = orientations or [(0.0, 0.0, 0.0, 1.0)] * len(goals)
        for (key, position, make_body), turn in zip(goals, turns, strict=True):
            if free.get(key):
                body = free[key].pop()
            else:
                body = make_body()
                self._goal_bodies.setdefault(key, []).append(body)
            p.resetBasePositionAndOrientation(body, position, turn, physicsClientId=self.client)
            used.append(body)
        self._goal_in_use = used
        return used


def _convert_to_obj(path: Path) -> Path:
    """Convert a GLB / GLTF / PLY scan to an OBJ cached beside it."""
    return convert_mesh(path, path.with_suffix(path.suffix + ".converted.obj"))


def convert_mesh(source: Path, target: Path, transform: np.ndarray | None = None) -> Path:
    """``source`` (any mesh trimesh reads), moved by the 4 x 4 ``transform`` if given, as an
    OBJ at ``target``, written atomically; reused when it is newer than the source. A
    ``ValueError`` names a file trimesh cannot read."""
    import trimesh  # only scans need it: the procedural houses' workers never load it

    if target.is_file() and target.stat().st_mtime >= source.stat().st_mtime:
        return target
    try:
        mesh = trimesh.load(source, force="mesh")
    except Exception as error:  # trimesh raises many kinds of errors for bad files
        raise MeshSceneError(f"could not read mesh scene {source}: {error}") from error
    if transform is not None:
        mesh.apply_transform(transform)
    target.parent.mkdir(parents=True, exist_ok=True)
    with replacing(target) as temporary:
        mesh.export(temporary, file_type="obj")
    return target
