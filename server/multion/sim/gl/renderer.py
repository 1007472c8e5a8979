"""The ``gl`` renderer: one world's bodies in OpenGL, drawn from the camera's pose.

One pass writes, per pixel, one RGBA32F texel: the colour packed as ``r·65536 + g·256 + b``
(exact in a float32), the planar depth in metres, and the body id (-1 for background); one
read-back per image gives RGB, depth and segmentation. The shading repeats TinyRenderer's
(bullet3 ``examples/TinyRenderer/TinyRenderer.cpp``, ``Shader::fragment``): the texel at
``(int(u·w), int(v·h))`` (black outside the image), times the shape's colour, truncated to
an integer; then ``int(ambient·c + diffuse·max(0, n·l)·c)`` capped at 255, with the
interpolated normal renormalised, no specular (the camera asks for none) and no shadow.
Faces seen from behind are culled and a later triangle wins a depth tie, as there.

The camera's view and projection are PyBullet's own matrices; TinyRenderer samples each
pixel half a pixel off OpenGL's centres, so the projection is shifted by half a pixel, as
for the EGL plugin (``EGL_PIXEL_SHIFT`` in :mod:`multion.sim.camera`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from multion.sim.bullet import pybullet as p
from multion.sim.gl import context
from multion.sim.gl.scene import (
    RECT_COLUMNS,
    ShapeVertices,
    Transform,
    body_ids,
    body_shapes,
    build_atlas,
    in_world,
    inertial_inverse,
    link_pose,
    load_image,
)

if TYPE_CHECKING:
    import moderngl

TINY_LIGHT_DIRECTION = (-50.0, 30.0, 100.0)
"""TinyRenderer's light direction when none is given and z is up
(``TinyRendererVisualShapeConverter::render``), normalised before use."""
WHITE = 255.0 * 65536 + 255.0 * 256 + 255.0
"""The packed colour of the background: TinyRenderer clears to white."""
HIDDEN_BELOW = -50.0
"""Bodies parked lower than this (the world hides goals at z = -100) are not drawn."""

VERTEX_SHADER = """
#version 330
uniform mat4 projection;
uniform mat4 view;
uniform mat4 model;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
in vec4 in_colour;
in vec4 in_rect;
in float in_body;
out vec3 v_normal;
out vec2 v_uv;
out float v_depth;
flat out vec4 v_colour;
flat out vec4 v_rect;
flat out float v_body;
void main() {
    vec4 eye = view * (model * vec4(in_position, 1.0));
    v_depth = -eye.z;
    v_normal = mat3(model) * in_normal;
    v_uv = in_uv;
    v_colour = in_colour;
    v_rect = in_rect;
    v_body = in_body;
    gl_Position = projection * eye;
}
"""

FRAGMENT_SHADER = """
#version 330
uniform sampler2D atlas;
uniform vec3 light_direction;
uniform float ambient;
uniform float diffuse;
in vec3 v_normal;
in vec2 v_uv;
in float v_depth;
flat in vec4 v_colour;
flat in vec4 v_rect;
flat in float v_body;
out vec4 texel;
void main() {
    vec3 colour = vec3(255.0);
    if (v_rect.z > 0.0) {
        ivec2 size = ivec2(v_rect.zw);
        ivec2 at = ivec2(v_uv * v_rect.zw);  // truncates toward zero, like int()
        if (at.x < 0 || at.y < 0 || at.x >= size.x || at.y >= size.y) {
            colour = vec3(0.0);
        } else {
            colour = floor(texelFetch(atlas, ivec2(v_rect.xy) + at, 0).rgb * 255.0 + 0.5);
        }
    }
    colour = floor(colour * v_colour.rgb);
    float lit = max(0.0, dot(normalize(v_normal), light_direction));
    vec3 shaded = min(floor(ambient * colour + (diffuse * lit) * colour), vec3(255.0));
    texel = vec4(shaded.r * 65536.0 + shaded.g * 256.0 + shaded.b, v_depth, v_body, 1.0);
}
"""

_ATTRIBUTES = (
    "3f 3f 2f 4f 4f 1f",
    "in_position",
    "in_normal",
    "in_uv",
    "in_colour",
    "in_rect",
    "in_body",
)


@dataclass
class _Dynamic:
    """A body drawn at its current pose: one vertex array per (link, texture)."""

    body: int
    link: int
    vao: moderngl.VertexArray
    buffer: moderngl.Buffer
    texture: moderngl.Texture
    vertices: int


@dataclass(frozen=True)
class GLImage:
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32, planar depth in metres
    segmentation: np.ndarray  # (H, W) int32 body ids, -1 for background


class GLRenderer:
    """The GL mirror of one PyBullet world: build it once the world's scene is loaded;
    bodies created later (goals) join on the next :meth:`render`."""

    def __init__(
        self,
        client: int,
        static_bodies: Iterable[int],
        body_textures: Mapping[int, Path] | None = None,
    ) -> None:
        self.client = client
        self.body_textures = dict(body_textures or {})
        self.static_bodies = set(static_bodies)
        self.drawn_bodies: set[int] = set()
        """Bodies with at least one shape in the GL scene (tests compare it with PyBullet's)."""
        self._known: set[int] = set()
        self._dynamic: list[_Dynamic] = []
        self._base_offsets: dict[int, Transform] = {}
        self._textures: dict[Path, moderngl.Texture] = {}
        self._targets: dict[
            tuple[int, int], tuple[moderngl.Framebuffer, moderngl.Texture, moderngl.Renderbuffer]
        ] = {}
        self._closed = False
        with context.current() as ctx:
            self.program = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
            self._empty_texture = ctx.texture((1, 1), 3, bytes(3))
            shapes = []
            for body in body_ids(client):
                if body in self.static_bodies:
                    self._known.add(body)
                    shapes += body_shapes(client, body, self.body_textures.get(body))
            self._static = self._upload_static(ctx, shapes)
            self._add_new_bodies(ctx)

    # ------------------------------------------------------------------ building
    def _upload_static(
        self, ctx: moderngl.Context, shapes: list[ShapeVertices]
    ) -> tuple[moderngl.VertexArray, moderngl.Buffer, moderngl.Texture, int] | None:
        if not shapes:
            return None
        images = {s.texture: load_image(s.texture) for s in shapes if s.texture is not None}
        atlas = build_atlas(images)
        rows = []
        for shape in shapes:
            world = in_world(shape, link_pose(self.client, shape.body, shape.link))
            if shape.texture is not None:
                world[:, RECT_COLUMNS] = atlas.places[shape.texture]
            rows.append(world)
            self.drawn_bodies.add(shape.body)
        vertices = np.concatenate(rows).astype(np.float32)
        texture = ctx.texture(atlas.pixels.shape[1::-1], 3, atlas.pixels.tobytes())
        texture.filter = (ctx.NEAREST, ctx.NEAREST)
        buffer = ctx.buffer(vertices.tobytes())
        vao = ctx.vertex_array(self.program, [(buffer, *_ATTRIBUTES)])
        return vao, buffer, texture, len(vertices)

    def _add_new_bodies(self, ctx: moderngl.Context) -> None:
        """Bodies PyBullet holds that this scene has not seen: drawn at their pose."""
        if p.getNumBodies(physicsClientId=self.client) == len(self._known):
            return
        for body in body_ids(self.client):
            if body in self._known:
                continue
            self._known.add(body)
            self._base_offsets[body] = inertial_inverse(self.client, body)
            for shape in body_shapes(self.client, body, self.body_textures.get(body)):
                vertices = shape.vertices
                texture = self._empty_texture
                if shape.texture is not None:
                    texture = self._texture(ctx, shape.texture)
                    vertices = vertices.copy()
                    vertices[:, RECT_COLUMNS] = (0, 0, *texture.size)
                buffer = ctx.buffer(vertices.astype(np.float32).tobytes())
                vao = ctx.vertex_array(self.program, [(buffer, *_ATTRIBUTES)])
                self._dynamic.append(
                    _Dynamic(body, shape.link, vao, buffer, texture, len(vertices))
                )
                self.drawn_bodies.add(body)

    def _texture(self, ctx: moderngl.Context, path: Path) -> moderngl.Texture:
        """A moving body's texture, uploaded once per scene (flipped, as TinyRenderer reads)."""
        if path not in self._textures:
            image = np.ascontiguousarray(load_image(path)[::-1])
            texture = ctx.texture(image.shape[1::-1], 3, image.tobytes())
            texture.filter = (ctx.NEAREST, ctx.NEAREST)
            self._textures[path] = texture
        return self._textures[path]

    # ------------------------------------------------------------------ drawing
    def render(
        self,
        width: int,
        height: int,
        view: tuple[float, ...],
        projection: tuple[float, ...],
        lighting: tuple[float, float],
        far: float,
    ) -> GLImage:
        """Draw the world as it is now; ``view`` and ``projection`` are PyBullet's
        column-major matrices."""
        if self._closed:
            raise RuntimeError("this GL scene was closed")
        with context.current() as ctx:
            self._add_new_bodies(ctx)
            framebuffer = self._target(ctx, width, height)
            framebuffer.use()
            framebuffer.clear(WHITE, far, -1.0, 0.0, depth=1.0)  # white, far, no body
            ctx.enable(ctx.DEPTH_TEST | ctx.CULL_FACE)
            ctx.depth_func = "<="
            ctx.front_face = "ccw"
            program = self.program
            _uniform(program, "projection").write(struct.pack("16f", *projection))
            _uniform(program, "view").write(struct.pack("16f", *view))
            direction = np.asarray(TINY_LIGHT_DIRECTION) / np.linalg.norm(TINY_LIGHT_DIRECTION)
            _uniform(program, "light_direction").value = tuple(float(v) for v in direction)
            _uniform(program, "ambient").value = lighting[0]
            _uniform(program, "diffuse").value = lighting[1]
            model = _uniform(program, "model")
            identity = struct.pack("16f", *np.eye(4, dtype=np.float32).reshape(-1))
            if self._static is not None:
                vao, _, texture, count = self._static
                model.write(identity)
                texture.use(0)
                vao.render(vertices=count)
            for part in self._dynamic:
                pose = link_pose(self.client, part.body, part.link, self._base_offsets[part.body])
                if pose[2, 3] < HIDDEN_BELOW:
                    continue
                model.write(pose.T.astype(np.float32).tobytes())
                part.texture.use(0)
                part.vao.render(vertices=part.vertices)
            raw = framebuffer.read(components=4, dtype="f4")
        texels = np.frombuffer(raw, dtype=np.float32).reshape(height, width, 4)[::-1]
        packed = texels[:, :, 0].astype(np.int32)
        rgb = np.empty((height, width, 3), dtype=np.uint8)
        rgb[:, :, 0] = packed >> 16
        rgb[:, :, 1] = (packed >> 8) & 255
        rgb[:, :, 2] = packed & 255
        return GLImage(
            rgb=rgb,
            depth=np.ascontiguousarray(texels[:, :, 1]),
            segmentation=texels[:, :, 2].astype(np.int32),
        )

    def _target(self, ctx: moderngl.Context, width: int, height: int) -> moderngl.Framebuffer:
        key = (width, height)
        if key not in self._targets:
            colour = ctx.texture((width, height), 4, dtype="f4")
            depth = ctx.depth_renderbuffer((width, height))
            self._targets[key] = (ctx.framebuffer([colour], depth), colour, depth)
        return self._targets[key][0]

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Release every GL object of this scene (the context stays for the next scene)."""
        if self._closed:
            return
        self._closed = True
        with context.current():
            objects: list[Any] = [self.program, self._empty_texture]
            if self._static is not None:
                objects += list(self._static[:3])
            for part in self._dynamic:
                objects += [part.vao, part.buffer]
            objects += list(self._textures.values())
            for target in self._targets.values():
                objects += list(target)
            for gl_object in objects:
                gl_object.release()
        self._dynamic.clear()
        self._textures.clear()
        self._targets.clear()


def _uniform(program: moderngl.Program, name: str) -> moderngl.Uniform:
    import moderngl

    member = program[name]
    assert isinstance(member, moderngl.Uniform), name
    return member


def shifted_projection(projection: tuple[float, ...], width: int, height: int) -> tuple[float, ...]:
    """PyBullet's projection moved by half a pixel right and up, so that OpenGL's pixel
    centres sample the rays TinyRenderer samples."""
    matrix = list(projection)
    dx, dy = 1.0 / width, 1.0 / height
    for column in range(4):
        matrix[column * 4 + 0] += dx * matrix[column * 4 + 3]
        matrix[column * 4 + 1] += dy * matrix[column * 4 + 3]
    return tuple(matrix)
