"""``GET /v1/health`` and ``GET /v1/spec``."""

from __future__ import annotations

from fastapi import APIRouter
from gymnasium import spaces

from multion.api.deps import MsgpackResponse, Registry, Settings
from multion.api.openapi import answers
from multion.config.codec import config_ranges, env_config_to_dict
from multion.config.reference import DEFAULT_SOURCES
from multion.config.sim import RENDERERS
from multion.config.task import SENSORS, EnvConfig
from multion.task.memory import mib
from multion.task.spaces import build_observation_space
from multion_client.constants import GOAL_CATEGORIES, GOAL_SETS, NUM_ACTIONS, Action
from multion_client.protocol import (
    API_VERSION,
    HEALTH_PATH,
    HEALTH_STATUSES,
    SPEC_PATH,
    Health,
    ServerSpec,
)

router = APIRouter(tags=["meta"], default_response_class=MsgpackResponse)


@router.get(
    HEALTH_PATH,
    summary="Server status",
    description="API version, the simulator workers (pid, liveness, environments held and their "
    "memory estimates), and the number of live sessions and environments. Status is `degraded` "
    "while a worker is being replaced.",
    responses=answers(200, Health),
)
async def health(registry: Registry) -> MsgpackResponse:
    workers = [
        {
            "slot": w.slot,
            "pid": w.pid,
            "alive": w.alive,
            "ready": w.ready.done(),
            "envs": w.env_count,
            "reserved_mib": mib(w.reserved_bytes),
            "limit_mib": mib(w.memory_limit_bytes),
        }
        for w in registry.pool.workers
    ]
    healthy = all(w["alive"] and w["ready"] for w in workers)
    report = Health(
        status=HEALTH_STATUSES[0] if healthy else HEALTH_STATUSES[1],
        api_version=API_VERSION,
        workers=workers,
        workers_replaced=registry.pool.replaced,
        sessions=registry.live_sessions(),
        envs=registry.live_envs(),
        sessions_reaped=registry.reaped,
    )
    return MsgpackResponse(report.to_wire())


@router.get(
    SPEC_PATH,
    summary="Task and API description",
    description="The actions, goal categories (of each goal set) and sensors, the default environment config "
    "(the shape of `config` in a create request) and the allowed values of its fields, where "
    "the defaults come from (the paper, or the reference code's file and line), the "
    "observation and action spaces of the default config, and this server's limits.",
    responses=answers(200, ServerSpec),
)
async def spec(settings: Settings, registry: Registry) -> MsgpackResponse:
    default = EnvConfig()
    # What "auto" resolves to, and the env's metadata, come from a worker's ready message: the
    # server process itself never loads the simulator (nor opens a GL context) to find out.
    report = await registry.pool.report()
    body = ServerSpec(
        api_version=API_VERSION,
        actions={a.name: a.value for a in Action},
        goal_categories=list(GOAL_CATEGORIES),
        sensors=list(SENSORS),
        defaults=env_config_to_dict(default),
        ranges=config_ranges(),
        observation_space=build_observation_space(default),
        action_space=spaces.Discrete(NUM_ACTIONS),
        metadata=report.env_metadata if report else {},
        autoreset_mode="same_step",
        renderer={
            "choices": list(RENDERERS),
            "default": default.camera.renderer,
            "auto": report.renderer_auto if report else None,
            "gl_unavailable": report.gl_unavailable if report else None,
        },
        limits={
            "max_sessions": settings.max_sessions,
            "max_envs_per_session": settings.max_envs_per_session,
            "max_envs_total": settings.max_envs_total,
            "idle_timeout_s": settings.idle_timeout_s,
            "max_request_bytes": settings.max_request_bytes,
            "worker_memory_mb": settings.worker_memory_mb,
            "workers": settings.workers,
        },
        goal_sets={name: list(names) for name, names in GOAL_SETS.items()},
        sources=dict(DEFAULT_SOURCES),
    )
    return MsgpackResponse(body.to_wire())
