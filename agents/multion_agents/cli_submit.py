"""``multion submit``: play an agent through a leaderboard run on a challenge server.

Examples::

    export MULTION_TOKEN=mlb_...            # the team's token (kept out of shell history)
    multion submit --server https://host:8000 --track 3-on --phase minival --agent explorer
    multion submit --server URL --track 1-on --phase test-standard --agent oracle-map \\
        --checkpoint runs/om/checkpoint.pt --method "OracleMap (ours)" --paper-url https://…
    multion submit --server URL --resume RUN_ID --agent explorer   # after a crash
    multion submit --server URL --track 3-on --phase test-standard --agent explorer --envs 2

Any agent of ``multion eval`` runs: baselines, import paths and learned agents with their
checkpoint. The server picks the hidden episodes and scores them; the agent sees the sensors it
asked for, which the track must allow. A camera of another size than the track's is served by
resizing the images here (nearest neighbour), for learned agents trained on small images.
"""

from __future__ import annotations

import argparse
import copy
import sys
from typing import Any

import numpy as np

from multion.config.errors import UsageError
from multion_agents.agent import Agent, AgentError
from multion_agents.evaluate import EvalSettings, episode_seed, resolve_agent, resolve_config
from multion_client.client import Client
from multion_client.errors import MultiONError, RunOver, ServerUnavailable
from multion_client.run import RunEnv, describe_run, token_from_env


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--server", required=True, help="the challenge server's URL")
    parser.add_argument(
        "--token", default=None, help="team token (default: the MULTION_TOKEN variable)"
    )
    parser.add_argument("--track", default=None, help="track name, e.g. 3-on")
    parser.add_argument("--phase", default=None, help="phase: minival, test-standard, …")
    parser.add_argument("--agent", required=True, help="an agent of `multion eval`")
    parser.add_argument("--checkpoint", default=None, help="checkpoint of a learned agent")
    parser.add_argument("--deterministic", action="store_true", help="learned agents: argmax")
    parser.add_argument("--method", default=None, help="method name shown on the leaderboard")
    parser.add_argument("--paper-url", default=None)
    parser.add_argument("--code-url", default=None)
    parser.add_argument("--seed", type=int, default=0, help="agent seed (default 0)")
    parser.add_argument("--resume", default=None, metavar="RUN_ID", help="continue this run")
    parser.add_argument(
        "--envs",
        type=int,
        default=1,
        metavar="K",
        help="play K episodes at once (one agent each, in threads; up to the challenge's "
        "max_envs_per_run); the server still chooses every episode (default 1)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    settings = EvalSettings(
        agent=args.agent, checkpoint=args.checkpoint, deterministic=args.deterministic
    )
    try:
        cls = resolve_agent(settings)
    except UsageError as error:
        return _fail(str(error))
    if args.resume is None and not (args.track and args.phase):
        return _fail("a new run needs --track and --phase (or --resume RUN_ID)")
    try:
        status = submit(args, cls)
    except ServerUnavailable as error:
        return _fail(f"cannot reach {args.server}: {error} (resume with --resume)")
    except UsageError as error:  # before MultiONError: the local config errors are wire errors too
        return _fail(str(error))
    except MultiONError as error:
        return _fail(f"the server refused: {error}")
    print(describe_run(status))
    return 0


def submit(args: argparse.Namespace, cls: type[Agent]) -> Any:
    """Play every remaining episode of a (new or resumed) run; returns its final RunStatus."""
    token = token_from_env(args.token)
    camera = (cls.config_overrides or {}).get("camera", {})
    if args.resume is None:
        with Client(args.server, token=token) as client:
            track = _track(client.challenge(), args.track)
        _check_overrides(cls, track)
        cls(seed=args.seed).configure(run_config(cls, track))  # refused before the run starts
        envs = RunEnv.lanes(
            args.server, args.track, args.phase, args.method or args.agent, token=token,
            sensors=list(cls.sensors), maps=oracle_maps(cls), paper_url=args.paper_url,
            code_url=args.code_url, num_envs=args.envs,
        )  # fmt: skip
        env = envs[0]
        print(
            f"run {env.run_id}: {env.num_episodes} episodes, {len(envs)} at once "
            f"(resume with --resume {env.run_id})"
        )
    else:
        env = RunEnv(args.server, token=token, run_id=args.resume)
        envs = [env] + [
            RunEnv(args.server, token=token, run_id=args.resume, lane=k)
            for k in range(1, env.num_envs)
        ]
        if env.run_done:  # over already (finished, ended or failed): nothing to play
            print(f"run {env.run_id} is over already: nothing left to play")
            return _closed(envs, env.status())
        with Client(args.server, token=token) as client:
            track = _track(client.challenge(), env.status().track)
    play_lanes(
        envs, cls, args.seed, _target_size(camera, track), progress=not args.quiet,
        config=run_config(cls, track),
    )  # fmt: skip
    return _closed(envs, env.status())


def _closed(envs: list[RunEnv], status: Any) -> Any:
    """``status``, once the lanes' connections are closed."""
    for lane in envs:
        lane.close()
    return status


def play_lanes(
    envs: list[Any],
    cls: type[Agent],
    seed: int = 0,
    image_size: tuple[int, int] | None = None,
    progress: bool = True,
    config: dict[str, Any] | None = None,
) -> None:
    """Play the lanes of one run at once, a thread and a fresh agent each (agents are seeded
    per episode number, so the lanes change no decision). ``config``: the run's resolved
    environment config, given to every agent (:func:`run_config`)."""
    from concurrent.futures import ThreadPoolExecutor

    from tqdm import tqdm

    total, finished = envs[0].num_episodes, sum(env.episodes_finished for env in envs)
    with tqdm(total=total, initial=finished, unit="ep", disable=not progress) as bar:
        if len(envs) == 1:
            play_run(envs[0], cls, seed, image_size, bar=bar, config=config)
            return
        with ThreadPoolExecutor(len(envs), thread_name_prefix="lane") as pool:
            for future in [
                pool.submit(play_run, env, cls, seed, image_size, bar=bar, config=config)
                for env in envs
            ]:
                future.result()


def play_run(
    env: Any,
    cls: type[Agent],
    seed: int = 0,
    image_size: tuple[int, int] | None = None,
    progress: bool = True,
    bar: Any = None,
    config: dict[str, Any] | None = None,
) -> None:
    """Play the remaining episodes of a ``RunEnv`` (one lane) with a fresh agent of class
    ``cls``; the agent is re-seeded per episode from ``(seed, episode number)``, as
    ``multion eval`` does. ``bar``: a shared progress bar (else one of its own)."""
    from tqdm import tqdm

    agent = cls(seed=seed)
    if config is not None:
        agent.configure(copy.deepcopy(config))
    visible = set(cls.sensors)
    own_bar = bar is None
    if own_bar:
        bar = tqdm(
            total=env.num_episodes, initial=env.episodes_finished, unit="ep", disable=not progress
        )
    try:
        while not env.run_done:
            observation, info = env.reset()
            agent.seed(episode_seed(seed, info["episode"]))
            agent.reset()
            done = False
            while not done:
                seen = _resized({k: v for k, v in observation.items() if k in visible}, image_size)
                observation, _, terminated, truncated, info = env.step(agent.act(seen))
                done = terminated or truncated
            bar.update(1)
            # a sealed or aggregate phase does not say how an episode ended: no "None"
            bar.set_postfix(last=info.get("end_reason") or "not shown")
    except RunOver:
        pass  # the server ended the run (time budget, timeouts): its status says why
    finally:
        if own_bar:
            bar.close()


def _track(challenge: dict[str, Any], name: str) -> dict[str, Any]:
    for track in challenge["tracks"]:
        if track["name"] == name:
            found: dict[str, Any] = track
            return found
    raise AgentError(
        f"the server has no track {name!r}; tracks: {[t['name'] for t in challenge['tracks']]}"
    )


def _check_overrides(cls: type[Agent], track: dict[str, Any]) -> None:
    missing = [s for s in cls.sensors if s not in track["sensors"]]
    if missing:
        raise AgentError(
            f"agent {cls.__name__} needs sensor(s) {missing}, which track {track['name']!r} does "
            f"not allow (it allows {track['sensors']})"
        )
    other = set(cls.config_overrides or {}) - {"maps", "camera"}
    if other:
        raise AgentError(f"agent {cls.__name__} changes {sorted(other)}, which a track fixes")


TRACK_RULES = ("max_steps", "num_distractors", "success_distance", "found_budget", "goal_set")
"""The task fields a track fixes beside m (``GET /v1/challenge``; older servers send fewer)."""


def run_config(cls: type[Agent], track: dict[str, Any]) -> dict[str, Any]:
    """The resolved environment config a run of track ``track`` gives agent ``cls``: the track's
    task (m, step limit and rules: distractors, FOUND radius and budget, goal set), camera and
    oracle maps, the agent's own oracle-map settings over the track's, every other field the
    server's default. Images are resized to the agent's own camera size when it asks for one
    (``_resized``), so the agent sees its own width and height."""
    camera = {**track.get("camera", {})}
    size = _target_size((cls.config_overrides or {}).get("camera", {}), track)
    if size is not None:
        camera["height"], camera["width"] = size
    task = {"num_goals": track["num_goals"]}
    task.update({key: track[key] for key in TRACK_RULES if track.get(key) is not None})
    config = {"task": task, "camera": camera, "sensors": list(cls.sensors)}
    maps = {**track.get("maps", {}), **(oracle_maps(cls) or {})}
    if maps:
        config["maps"] = maps
    return resolve_config(config)


def oracle_maps(cls: type[Agent]) -> dict[str, Any] | None:
    """The agent's oracle-map options, if it reads an oracle map (other tracks refuse them)."""
    if not {"oracle_map", "oracle_ego_map"} & set(cls.sensors):
        return None
    return (cls.config_overrides or {}).get("maps")


def _target_size(camera: dict[str, Any], track: dict[str, Any]) -> tuple[int, int] | None:
    """The agent's image size (height, width) when it differs from the track's."""
    if not camera:
        return None
    want = (int(camera.get("height", 256)), int(camera.get("width", 256)))
    have = (int(track["camera"].get("height", 256)), int(track["camera"].get("width", 256)))
    return None if want == have else want


def _resized(observation: dict[str, np.ndarray], size: tuple[int, int] | None) -> dict[str, Any]:
    if size is None:
        return observation
    out = dict(observation)
    for key in ("rgb", "depth", "goal_mask"):
        if key in out:
            image = out[key]
            rows = (np.arange(size[0]) * image.shape[0]) // size[0]
            cols = (np.arange(size[1]) * image.shape[1]) // size[1]
            out[key] = image[rows][:, cols]
    return out


def _fail(message: str) -> int:
    print(f"multion submit: {message}", file=sys.stderr)
    return 2
