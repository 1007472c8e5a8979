"""``GET /v1/health`` and ``GET /v1/spec``."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from starlette.concurrency import run_in_threadpool

from multion.api.config_io import env_config_to_dict
from multion.api.deps import MsgpackResponse, Registry, Settings
from multion.sim.camera import RENDERERS, resolve_renderer
from multion.task.env import SENSORS, EnvConfig, MultiONEnv, build_observation_space
from multion_client.constants import GOAL_CATEGORIES, Action
from multion_client.protocol import API_VERSION, HEALTH_PATH, SPEC_PATH, space_to_wire

router = APIRouter(tags=["meta"], default_response_class=MsgpackResponse)

_MSGPACK = {"content": {"application/x-msgpack": {}}}


@router.get(
    HEALTH_PATH,
    summary="Server status",
    description="API version, the simulator workers (pid, liveness, environments held), and "
    "the number of live sessions and environments. Status is `degraded` while a worker is "
    "being replaced.",
    responses={200: {"description": "msgpack map", **_MSGPACK}},
)
async def health(registry: Registry) -> MsgpackResponse:
    workers = [
        {
            "slot": w.slot,
            "pid": w.pid,
            "alive": w.alive,
            "ready": w.ready.done(),
            "envs": w.env_count,
        }
        for w in registry.pool.workers
    ]
    healthy = all(w["alive"] and w["ready"] for w in workers)
    return MsgpackResponse(
        {
            "status": "ok" if healthy else "degraded",
            "api_version": API_VERSION,
            "workers": workers,
            "workers_replaced": registry.pool.replaced,
            "sessions": registry.live_sessions(),
            "envs": registry.live_envs(),
            "sessions_reaped": registry.reaped,
        }
    )


@router.get(
    SPEC_PATH,
    summary="Task and API description",
    description="The actions, goal categories and sensors, the default environment config "
    "(the shape of `config` in a create request), the observation and action spaces of the "
    "default config, and this server's limits.",
    responses={200: {"description": "msgpack map", **_MSGPACK}},
)
async def spec(request: Request, settings: Settings) -> MsgpackResponse:
    default = EnvConfig()
    body: dict[str, Any] = {
        "api_version": API_VERSION,
        "actions": {a.name: a.value for a in Action},
        "goal_categories": list(GOAL_CATEGORIES),
        "sensors": list(SENSORS),
        "defaults": env_config_to_dict(default),
        "observation_space": space_to_wire(build_observation_space(default)),
        "action_space": {"type": "Discrete", "n": len(Action), "start": 0},
        "metadata": dict(MultiONEnv.metadata),
        "autoreset_mode": "same_step",
        # what camera.renderer "auto" renders with on this server (probed once: EGL or tiny)
        "renderer": {
            "choices": list(RENDERERS),
            "default": default.camera.renderer,
            "auto": await run_in_threadpool(resolve_renderer, "auto"),
        },
        "limits": {
            "max_sessions": settings.max_sessions,
            "max_envs_per_session": settings.max_envs_per_session,
            "max_envs_total": settings.max_envs_total,
            "idle_timeout_s": settings.idle_timeout_s,
            "max_request_bytes": settings.max_request_bytes,
        },
    }
    return MsgpackResponse(body)
