"""``multion dataset …`` and ``multion scene …``: datasets and scene pictures / exports."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from multion.config.datasets import DatasetError, load_dataset, parse_task
from multion.config.errors import UsageError
from multion.scenes.obj_export import export_obj
from multion.scenes.registry import is_mesh_scene, layout_for
from multion.scenes.viz import scene_picture
from multion.sim.simulator import Simulator
from multion.task.generate import generate_dataset
from multion.task.multion_import import import_multion
from multion_client.constants import NUM_CATEGORIES


def add_dataset_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    gen = sub.add_parser(
        "generate", help="generate episodes for a task and split (seeded, reproducible)"
    )
    gen.add_argument("--task", default="3-on", help="m-ON task: 1-on, 2-on, 3-on … (default 3-on)")
    gen.add_argument("--split", default="val", choices=["train", "val", "test"])
    gen.add_argument("--episodes", type=int, default=1000, help="number of episodes (default 1000)")
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument(
        "--distractors",
        type=int,
        default=0,
        help="distractor cylinders per episode, 0..8-m (default 0, the paper's task)",
    )
    gen.add_argument(
        "--scenes", nargs="*", help="scene ids (default: the split's procedural houses)"
    )
    gen.add_argument("--out", required=True, type=Path, help="output file (.json.gz)")
    check = sub.add_parser("check", help="validate a dataset file and print a summary")
    check.add_argument("path", type=Path)
    imp = sub.add_parser(
        "import-multion",
        help="convert an original MultiON episode file (MultiNav-v1) to a dataset on your scans",
    )
    imp.add_argument(
        "path", type=Path, metavar="FILE", help="MultiNav-v1 episodes (.json or .json.gz)"
    )
    imp.add_argument(
        "--scenes",
        required=True,
        type=Path,
        metavar="DIR",
        help="directory holding the scans the file's scene ids name (e.g. mp3d/<scan>/<scan>.glb)",
    )
    imp.add_argument(
        "--out",
        required=True,
        type=Path,
        help="output dataset (.json.gz); the "
        "scans are converted to z-up OBJs in a scenes/ directory beside it",
    )
    imp.add_argument(
        "--up",
        default="y",
        choices=["y", "z"],
        help="the scans' up axis: y (glTF, HM3D, habitat exports; default) or z "
        "(Matterport3D's own meshes)",
    )
    imp.add_argument(
        "--split",
        default="val",
        choices=["train", "val", "test"],
        help="split recorded in the dataset (default val)",
    )


def run_dataset(args: argparse.Namespace) -> int:
    if args.action == "generate":
        if args.episodes <= 0:
            print("--episodes must be positive", file=sys.stderr)
            return 2
        num_goals = parse_task(args.task)
        if not 0 <= args.distractors <= NUM_CATEGORIES - num_goals:
            print(
                f"--distractors must be in 0..{NUM_CATEGORIES - num_goals} for {num_goals} goals",
                file=sys.stderr,
            )
            return 2
        path = generate_dataset(
            args.out,
            num_goals,
            args.split,
            args.episodes,
            args.seed,
            args.scenes,
            num_distractors=args.distractors,
        )
        print(f"wrote {path}")
        return 0
    if args.action == "import-multion":
        return _import_multion(args)

    try:
        episodes = load_dataset(args.path)
    except DatasetError as error:
        print(f"invalid dataset: {error}", file=sys.stderr)
        return 1
    scenes = sorted({e.scene_id for e in episodes})
    lengths = [sum(e.geodesic_distances) for e in episodes if e.geodesic_distances]
    print(
        f"{args.path}: {len(episodes)} episodes, {episodes[0].num_goals} goals and "
        f"{len(episodes[0].distractors)} distractors each, {len(scenes)} scenes"
    )
    if lengths:
        print(
            f"total geodesic length: mean {sum(lengths) / len(lengths):.2f} m, "
            f"min {min(lengths):.2f} m, max {max(lengths):.2f} m"
        )
    return 0


def _import_multion(args: argparse.Namespace) -> int:
    if not args.path.is_file():
        print(f"episode file not found: {args.path}", file=sys.stderr)
        return 2
    if not args.scenes.is_dir():
        print(f"--scenes {args.scenes} is not a directory", file=sys.stderr)
        return 2
    try:
        result = import_multion(args.path, args.scenes, args.out, up=args.up, split=args.split)
    except DatasetError as error:
        print(f"cannot import: {error}", file=sys.stderr)
        return 1
    first = result.episodes[0]
    print(
        f"wrote {result.path}: {len(result.episodes)} episodes ({first.num_goals} goals, "
        f"{len(first.distractors)} distractors each) in {len(result.scenes)} scans"
    )
    if result.skipped:
        print(f"left out {len(result.skipped)} episodes: " + "; ".join(result.skipped[:5]))
    if result.geodesic_errors:
        errors = sorted(abs(e) for e in result.geodesic_errors)
        print(
            f"total geodesic measured here vs the file's info.geodesic_distance: median "
            f"difference {errors[len(errors) // 2]:.2f} m, largest {errors[-1]:.2f} m"
        )
    print(
        f"play it: multion eval --dataset {result.path} --task {first.num_goals}-on "
        "--agent oracle-planner"
    )
    return 0


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    pic = sub.add_parser("picture", help="draw a scene from above with its navigable area (PNG)")
    pic.add_argument("scene_id", help="house-00042, room-6x4, or a mesh file path")
    pic.add_argument("--out", type=Path, required=True)
    exp = sub.add_parser("export", help="export a procedural scene as a Wavefront OBJ mesh")
    exp.add_argument("scene_id")
    exp.add_argument("--out", type=Path, required=True)


def run_scene(args: argparse.Namespace) -> int:
    try:
        layout = None if is_mesh_scene(args.scene_id) else layout_for(args.scene_id)
    except UsageError as error:  # an unknown scene id
        print(error, file=sys.stderr)
        return 2
    if args.action == "export":
        if layout is None:
            print("only procedural scenes can be exported", file=sys.stderr)
            return 2
        print(f"wrote {export_obj(layout, args.out)}")
        return 0

    sim = Simulator()
    try:
        grid = sim.load_scene(args.scene_id)
    finally:
        sim.close()
    image = scene_picture(layout, grid.navigable, grid.origin, grid.cell_size)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    image.save(args.out)
    print(f"wrote {args.out} ({grid.navigable.sum() * grid.cell_size**2:.1f} m² navigable)")
    return 0
