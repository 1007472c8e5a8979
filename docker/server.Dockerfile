# MultiON server: simulator + FastAPI/uvicorn, N simulator worker processes.
#   docker build -f docker/server.Dockerfile -t multion-server .      (from the repository root)
#   docker run --rm -p 8000:8000 multion-server
#
# Python 3.11: pybullet 3.2.x ships manylinux wheels for CPython 3.11 but not 3.12, and
# scikit-fmm ships no wheels at all, so a builder stage with a C compiler makes the wheels and
# the runtime stage stays slim.
#
# camera.renderer "gl" (the MultiON 2.0 challenge's tracks) draws through EGL with Mesa's
# llvmpipe where there is no GPU: Debian 12's Mesa 22.3 and libglvnd 1.6, pinned here with the
# base image's release, so that a rebuild draws with the same OpenGL as the image it replaces.

FROM python:3.11-slim-bookworm AS build
RUN apt-get update \
    && apt-get install -y --no-install-recommends build-essential \
    && rm -rf /var/lib/apt/lists/*
WORKDIR /src
COPY pyproject.toml README.md ./
COPY client ./client
COPY server ./server
COPY agents ./agents
# [postgres]: psycopg, for replicas sharing one PostgreSQL (docker-compose.replicas.yml).
RUN pip wheel --no-cache-dir --wheel-dir /wheels ./client ".[postgres]"

FROM python:3.11-slim-bookworm
RUN apt-get update \
    && apt-get install -y --no-install-recommends libstdc++6 \
        "libegl1=1.6.*" "libgl1=1.6.*" "libegl-mesa0=22.3.*" "libgl1-mesa-dri=22.3.*" \
    && rm -rf /var/lib/apt/lists/*
COPY --from=build /wheels /wheels
# The same packages as `pip install ./client ".[postgres]"`, from the wheels built above.
RUN pip install --no-cache-dir --no-index --find-links /wheels "multion-pybullet[postgres]" multion-client \
    && rm -rf /wheels \
    && useradd --create-home multion
USER multion
WORKDIR /home/multion
EXPOSE 8000
# Extra dataset directories clients may name: mount them and add `--dataset-dir /data`.
HEALTHCHECK --interval=30s --timeout=5s --start-period=60s \
    CMD python -c "import httpx, sys; sys.exit(httpx.get('http://127.0.0.1:8000/v1/health').status_code != 200)"
CMD ["multion", "serve", "--host", "0.0.0.0", "--port", "8000", "--workers", "2"]
