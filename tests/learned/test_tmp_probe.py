import csv
import os
from pathlib import Path

from test_recipe_options import tiny_args

from multion_agents.learned.training_run import train


def test_probe(tmp_path: Path, room_dataset: Path) -> None:
    coef = float(os.environ.get("PROBE_HEAD", "1"))
    args = tiny_args(tmp_path, room_dataset, frames=64 * 2 * 60, found_head=coef, envs=2,
                     rollout_steps=64, found_prior=0.02)
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    for row in rows[::3]:
        print(row["frames"], row["train_success"], row["train_steps"], row["found_positive_share"][:6],
              row["found_prob_at_goal"][:6], row["found_prob_elsewhere"][:6], row["found_loss"][:6])
