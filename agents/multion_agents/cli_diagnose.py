"""``multion diagnose``: what a learned checkpoint sees and does (issue 51 item 1).

Examples::

    multion diagnose runs/pilot/no-map-paper/checkpoint.pt
    multion diagnose runs/pilot/no-map-all/checkpoint.pt --episodes 50 --out runs/pilot/no-map-all
    multion diagnose runs/pilot/no-map-found-head-all/checkpoint.pt --split train --no-probe

Prints, for the checkpoint: a linear probe's recall and precision of "the goal shows" on its
frozen image embedding by distance band (and ObjRecogMap's own recogniser), FOUND's mean
probability within the success distance of the goal and farther, and how the episodes it
plays end; for a FOUND head, how they would have ended with its gate lower (``--gates``; read
off the same episodes, :mod:`multion_agents.learned.found_gate`). ``--out`` also writes them to
``diagnosis.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

from multion.config.sim import RENDERERS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("checkpoint", help="a training checkpoint (checkpoint.pt)")
    parser.add_argument(
        "--episodes", type=int, default=20, help="episodes to play (default %(default)s)"
    )
    parser.add_argument(
        "--split",
        choices=("val", "train"),
        default="val",
        help="houses of the played episodes (default %(default)s; train: to choose a gate "
        "without looking at val)",
    )
    parser.add_argument(
        "--gates",
        default="0.05,0.1,0.2,0.3,0.4,0.5",
        help="FOUND head gates to read off the played episodes, in (0, 0.5] (default %(default)s)",
    )
    parser.add_argument(
        "--no-probe", action="store_true", help="skip the image-embedding probe: only play"
    )
    parser.add_argument(
        "--probe-frames",
        type=int,
        default=2000,
        help="train-house frames the probe learns from (200-100000; default %(default)s)",
    )
    parser.add_argument(
        "--held-out",
        type=int,
        default=600,
        help="val-house frames the probe is scored on (100-10000; default %(default)s)",
    )
    parser.add_argument(
        "--probe-steps", type=int, default=1000, help="probe training steps (default %(default)s)"
    )
    parser.add_argument(
        "--renderer",
        choices=RENDERERS,
        help="camera.renderer of the played and probed frames (default the config's; a checkpoint "
        "trained with gl at 128² plays fastest with gl, as `multion eval --set camera.renderer=gl`)",
    )
    parser.add_argument("--seed", type=int, default=0, help="frames and sampled actions' seed")
    parser.add_argument("--out", help="also write DIR/diagnosis.json")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    from multion.common.files import write_atomically
    from multion.config.errors import UsageError
    from multion_agents.agent import merge_overrides
    from multion_agents.learned.checkpoint import load_policy
    from multion_agents.learned.diagnose import (
        diagnosis_config,
        found_calls,
        probe_scores,
        recogniser_scores,
        view_frames,
    )
    from multion_agents.learned.found_gate import parse_gates
    from multion_agents.learned.train_options import VisionPretraining

    if not 1 <= args.episodes <= 1000:
        return _fail(f"--episodes must be in [1, 1000], got {args.episodes}")
    try:
        gates = parse_gates(args.gates)
    except ValueError as error:
        return _fail(str(error))
    try:
        settings = VisionPretraining(
            steps=args.probe_steps,
            samples=args.probe_frames,
            held_out=args.held_out,
            seed=args.seed,
        )
    except ValueError as error:
        return _fail(str(error).replace("pretrain_vision.", "probe ").replace("samples", "frames"))
    progress = not args.quiet
    try:
        policy, overrides, model = load_policy(args.checkpoint)
    except UsageError as error:
        return _fail(str(error))
    if args.renderer is not None:  # the machine's choice, as in `multion eval`
        overrides = merge_overrides(overrides, {"camera": {"renderer": args.renderer}})
    config = diagnosis_config(overrides, policy.sensors)
    result: dict[str, Any] = {"checkpoint": str(args.checkpoint), "model": model}
    print(
        f"multion diagnose {args.checkpoint}: {model}, 1-ON, {config.camera.width}² camera "
        f"({config.camera.renderer})"
    )
    if policy.image_encoder is not None and not args.no_probe:
        train, held_out = view_frames(config, settings, progress)
        probe = probe_scores(policy, train, held_out, settings)
        result["probe"] = [dataclasses.asdict(row) for row in probe]
        _print_bands(
            f"seeing the goal: a linear probe of the frozen image embedding ({len(train)} "
            f"train-house frames, {args.probe_steps} steps; scored on {len(held_out)} "
            "val-house frames, half facing the goal)",
            probe,
        )
        recogniser = recogniser_scores(policy, held_out)
        if recogniser is not None:
            result["recogniser"] = [dataclasses.asdict(row) for row in recogniser]
            _print_bands("the agent's own recogniser on the same val frames", recogniser)
    played = dataclasses.replace(config, split=args.split)
    calls = found_calls(policy, played, args.episodes, args.seed, progress, gates)
    result["found_calls"] = {"split": args.split, **dataclasses.asdict(calls)}
    reach = config.task.success_distance
    print(
        f"calling FOUND ({args.episodes} {args.split} episodes, sampled actions, seed {args.seed}):"
    )
    for label, steps, probability in (
        (f"within {reach:g} m of the goal:", calls.near_steps, calls.near_probability),
        ("farther:", calls.far_steps, calls.far_probability),
    ):
        print(f"  {label:<28}{steps:>7} steps, mean P(FOUND) {_share(probability)}")
    endings = ", ".join(f"{name} {count}" for name, count in sorted(calls.endings.items()))
    print(f"  episodes ended: {endings}")
    print(
        f"  episodes that came within {reach:g} m of the goal: {calls.reached}; with the goal "
        f"in view there: {calls.seen_in_reach} ({calls.in_view_steps} steps, mean P(FOUND) "
        f"{_share(calls.in_view_probability)})"
    )
    print(
        f"  not won of those: {calls.missed_in_reach}; steps within reach with the goal out of "
        f"view but seen earlier: {calls.seen_out_of_view_steps} (mean P(FOUND) "
        f"{_share(calls.seen_out_of_view_probability)})"
    )
    print(f"  episodes whose goal came into view (within {config.maps.view_distance:g} m): "
          f"{calls.saw_goal}")  # fmt: skip
    print(
        f"  2.5 m cells entered per episode: {_number(calls.cells_visited)}; in the episodes "
        f"that reached the step limit: {_number(calls.cells_at_step_limit)}"
    )
    if calls.gate_endings:
        print(
            f"the FOUND head's gate (played at {policy.found_gate:g}; at 1-ON the first FOUND "
            "ends the episode, so each lower gate is read off the same episodes):"
        )
        print(f"  {'gate':>6} {'success':>8} {'wrong FOUND':>12} {'step limit':>11}")
        for gate, counts in calls.gate_endings.items():
            print(
                f"  {gate:>6} {counts.get('success', 0):>8} "
                f"{counts.get('wrong_found', 0):>12} {counts.get('max_steps', 0):>11}"
            )
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        text = json.dumps(_finite(result), indent=2, allow_nan=False) + "\n"
        write_atomically(out / "diagnosis.json", text)
        print(f"wrote {out / 'diagnosis.json'}")
    return 0


def _print_bands(title: str, rows: list[Any]) -> None:
    print(title + ":")
    print(f"  {'band':>10} {'frames':>7} {'goal shows':>11} {'recall':>7} {'precision':>10}")
    for row in rows:
        if not row.frames:
            continue  # beyond the frames' max_distance
        low, high = row.band
        band = f"{low:g}-{high:g} m" if math.isfinite(high) else f"> {low:g} m"
        print(
            f"  {band:>10} {row.frames:>7} {row.in_view:>11} {_share(row.recall):>7} "
            f"{_share(row.precision):>10}"
        )


def _share(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.2f}"


def _number(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.1f}"


def _finite(value: Any) -> Any:
    """``value`` with non-finite floats (nan: undefined, inf: an open band) as None (JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def _fail(message: str) -> int:
    print(f"multion diagnose: {message}", file=sys.stderr)
    return 2
