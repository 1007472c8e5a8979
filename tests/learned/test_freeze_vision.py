"""``--freeze-vision`` (issue 51): PPO leaves the image encoder as ``--pretrain-vision`` left it,
so the features a learned map writes stay the same all run. The encoder's weights after updates
and after a resume, the rest of the policy still learning, and the option's checks."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from test_recipe_options import assert_resumes_only_with, tiny_args

from multion.config.ranges import ConfigError
from multion_agents.learned.checkpoint import load_checkpoint
from multion_agents.learned.train_options import VisionPretraining
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import TrainingRun

VISION = VisionPretraining(steps=20, samples=200, held_out=100, max_distance=4.0)


def _weights(state: dict[str, torch.Tensor], prefix: str) -> dict[str, torch.Tensor]:
    return {k: v.detach().clone() for k, v in state.items() if k.startswith(prefix)}


def _same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _encoder_before_and_after_two_updates(
    args: Args,
) -> tuple[dict[str, torch.Tensor], ...]:
    """The image encoder's and the GRU's weights after pretraining, then after two updates."""
    run = TrainingRun.start(args)
    with run:
        encoder = _weights(run.policy.state_dict(), "image_encoder.")
        gru = _weights(run.policy.state_dict(), "gru.")
        run.update()
        run.update()
        after = run.policy.state_dict()
        result = (encoder, gru, _weights(after, "image_encoder."), _weights(after, "gru."))
        run.finish()
    return result


def test_freeze_vision_needs_vision_pretraining() -> None:
    assert Args().freeze_vision is False  # off in the paper's recipe
    with pytest.raises(ConfigError, match="--freeze-vision .* it needs --pretrain-vision"):
        Args(freeze_vision=True)


def test_a_frozen_run_keeps_the_pretrained_encoder_and_trains_the_rest(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, frames=128, pretrain_vision=VISION,
                     freeze_vision=True)  # fmt: skip
    encoder, gru, encoder_after, gru_after = _encoder_before_and_after_two_updates(args)
    assert encoder and _same(encoder, encoder_after)
    assert gru and not _same(gru, gru_after)  # the policy still learns
    path = tmp_path / "run" / "checkpoint.pt"
    assert load_checkpoint(path)["args"]["freeze_vision"] is True
    # a resume freezes the loaded encoder again (requires_grad is not saved with the weights)
    assert_resumes_only_with(args, "freeze_vision")
    resumed = load_checkpoint(path)
    assert resumed["frames"] == 2 * args.frames
    assert _same(encoder, _weights(resumed["model"], "image_encoder."))


def test_without_it_ppo_changes_the_pretrained_encoder(tmp_path: Path, room_dataset: Path) -> None:
    """The control: the same run with the option off moves the encoder, so the test above would
    fail if freezing did nothing."""
    args = tiny_args(tmp_path, room_dataset, frames=128, pretrain_vision=VISION)
    encoder, _, encoder_after, _ = _encoder_before_and_after_two_updates(args)
    assert not _same(encoder, encoder_after)
