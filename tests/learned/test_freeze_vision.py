"""``--freeze-vision`` (issue 51): PPO leaves the image encoder as ``--pretrain-vision`` left it,
so the features a learned map writes stay the same all run. The encoder's weights after updates
and after a resume, the rest of the policy still learning, and the option's checks; the frozen
encoder's outputs kept from acting and replayed by the update, which no longer runs it."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from test_recipe_options import assert_resumes_only_with, tiny_args
from torch import Tensor, nn

from multion.config.codec import env_config_from_dict
from multion.config.ranges import ConfigError
from multion.task.spaces import build_observation_space
from multion_agents.bench.learner import synthetic_frames
from multion_agents.learned.checkpoint import load_checkpoint
from multion_agents.learned.models import build_policy, model_spec
from multion_agents.learned.policy import IMAGE_EMBEDDING, IMAGE_FEATURES, RecurrentPolicy
from multion_agents.learned.rollout import store_frame
from multion_agents.learned.rollout_envs import training_env_config
from multion_agents.learned.train_options import VisionPretraining
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import TrainingRun
from multion_agents.learned.vision_pretrain import freeze_image_encoder

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


# ---------------------------------------------------------------- the frozen encoder's outputs
STEPS, ENVS = 5, 3


def _policy_and_frames(agent: str) -> tuple[RecurrentPolicy, dict[str, Tensor]]:
    sensors = model_spec(agent).train_sensors
    config = training_env_config(1, sensors, 36, "train")
    torch.manual_seed(0)
    policy = build_policy(agent, config, hidden_size=32)
    space = build_observation_space(env_config_from_dict(config))
    return policy, synthetic_frames(space, policy.train_sensors, STEPS, ENVS, seed=0)


def _replay(policy: RecurrentPolicy, frames: dict[str, Tensor]) -> tuple[Tensor, Tensor]:
    starts = torch.zeros(STEPS, ENVS)
    starts[0] = 1.0
    with torch.no_grad():
        out = policy(frames, torch.zeros(STEPS, ENVS, dtype=torch.long), starts,
                     policy.initial_state(ENVS))  # fmt: skip
    return out.logits, out.value


def _acted(policy: RecurrentPolicy, frames: dict[str, Tensor]) -> dict[str, Tensor]:
    """The rollout's frames as acting keeps them, step by step (``rollout._act``)."""
    kept = dict(frames)
    for t in range(STEPS):
        store_frame(
            kept, t, slice(0, ENVS), policy.cache_images({k: v[t] for k, v in frames.items()})
        )
    return kept


@pytest.mark.parametrize("agent", ["no-map", "proj-neural-map", "obj-recog-map"])
def test_a_frozen_encoders_kept_outputs_replay_as_the_encoder_computes_them(agent: str) -> None:
    policy, frames = _policy_and_frames(agent)
    freeze_image_encoder(policy)
    kept = _acted(policy, frames)
    assert kept[IMAGE_EMBEDDING].shape == (STEPS, ENVS, 512)
    assert kept[IMAGE_FEATURES].shape[:2] == (STEPS, ENVS)
    logits, value = _replay(policy, frames)
    encoder = policy.image_encoder
    assert isinstance(encoder, nn.Module)
    calls: list[int] = []
    encoder.register_forward_hook(lambda module, inputs, output: calls.append(1))
    kept_logits, kept_value = _replay(policy, kept)
    assert calls == []  # the replay read the kept outputs, not the encoder
    torch.testing.assert_close(kept_logits, logits)
    torch.testing.assert_close(kept_value, value)


def test_a_learning_encoder_keeps_nothing_and_refuses_kept_outputs() -> None:
    policy, frames = _policy_and_frames("no-map")
    assert not policy.vision_frozen
    assert set(_acted(policy, frames)) == set(frames)  # its outputs change as it learns
    frozen, _ = _policy_and_frames("no-map")
    freeze_image_encoder(frozen)
    with pytest.raises(ValueError, match="cached image features need a frozen image encoder"):
        _replay(policy, _acted(frozen, frames))


def _encoder_batches(args: Args) -> list[int]:
    """The batch sizes the image encoder ran on during one rollout and update of a run."""
    run = TrainingRun.start(args)
    with run:
        batches: list[int] = []
        encoder = run.policy.image_encoder
        assert isinstance(encoder, nn.Module)
        encoder.register_forward_hook(lambda m, inputs, out: batches.append(out[1].shape[0]))
        run.update()
        run.finish()
    return batches


def test_a_frozen_runs_update_does_not_run_the_encoder(tmp_path: Path, room_dataset: Path) -> None:
    frozen = tiny_args(tmp_path / "frozen", room_dataset, frames=64, pretrain_vision=VISION,
                       freeze_vision=True)  # fmt: skip
    learning = tiny_args(tmp_path / "learning", room_dataset, frames=64, pretrain_vision=VISION)
    # acting runs it on at most the environments at once; the update on whole sequences
    assert max(_encoder_batches(frozen)) <= frozen.envs
    assert max(_encoder_batches(learning)) >= learning.rollout_steps
