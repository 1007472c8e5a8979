"""Regenerate the packaged episode datasets (1,000 episodes per task and split), as shipped.

    .venv/bin/python scripts/make_datasets.py --split val     # 1-on, 2-on, 3-on, 3-on-distractors
    .venv/bin/python scripts/make_datasets.py --split test
    .venv/bin/python scripts/make_datasets.py --split val --only 3-on-distractors

1,000 episodes per task and for the distractor variant (as the paper's test set).

One process per split builds each house once (the grids stay cached) and writes every file of
that split; the seeds are fixed, so the files are reproducible byte for byte.
"""

from __future__ import annotations

import argparse

from multion.config.datasets import DISTRACTOR_VARIANT, packaged_dataset_path, variant_name
from multion.task.generate import generate_dataset

SEEDS = {"val": 1, "test": 2}  # one seed per split; tasks differ through the per-scene streams


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=sorted(SEEDS), required=True)
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--distractor-episodes", type=int, default=1000)
    parser.add_argument("--only", nargs="*", help="variants to make, e.g. 1-on 3-on-distractors")
    args = parser.parse_args()
    variants = [(1, 0), (2, 0), (3, 0), (3, DISTRACTOR_VARIANT)]
    if args.only:
        variants = [v for v in variants if variant_name(*v) in args.only]
    for num_goals, distractors in variants:
        count = args.distractor_episodes if distractors else args.episodes
        path = packaged_dataset_path(num_goals, args.split, distractors)
        generate_dataset(
            path, num_goals, args.split, count, SEEDS[args.split],
            num_distractors=distractors,
        )  # fmt: skip
        print(f"wrote {path}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
