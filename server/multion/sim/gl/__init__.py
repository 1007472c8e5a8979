"""The ``gl`` renderer: OpenGL 3.3 through moderngl and a headless EGL context, drawing the
bodies of the PyBullet world (issue 43). See ``docs/rendering.md``."""
