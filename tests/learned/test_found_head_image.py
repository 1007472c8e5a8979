"""``--found-head-reads-image`` (issue 51): the FOUND head reads the frame's image embedding
beside the GRU output. Without it nothing changes; with it the frame reaches FOUND through the
head's new columns and nothing else, and a checkpoint acts with it and resumes only with it."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from rollouts import sample_frames, space_for
from test_recipe_options import assert_resumes_only_with, tiny_args

from multion.config.ranges import ConfigError
from multion_agents.learned.checkpoint import load_checkpoint, load_policy
from multion_agents.learned.models import model_spec
from multion_agents.learned.policy import PolicyOutput, RecurrentPolicy
from multion_agents.learned.train_settings import Args
from multion_agents.learned.training_run import train


def _policy(name: str, reads_image: bool, seed: int = 0) -> RecurrentPolicy:
    torch.manual_seed(seed)
    return model_spec(name).build(
        space_for(name), found_head=True, found_head_reads_image=reads_image
    )


def _run(policy: RecurrentPolicy, frames: dict[str, torch.Tensor]) -> PolicyOutput:
    steps, batch = frames["goal"].shape[:2]
    starts = torch.zeros(steps, batch)
    starts[0] = 1
    previous = torch.zeros(steps, batch, dtype=torch.long)
    inputs = {k: v for k, v in frames.items() if k in policy.sensors}
    never = torch.zeros(steps, batch)  # the gate closed everywhere: the actor's logits unmasked
    with torch.no_grad():
        return policy(inputs, previous, starts, policy.initial_state(batch), never)


def _logit(output: PolicyOutput) -> torch.Tensor:
    assert output.found_logit is not None
    return output.found_logit


@pytest.mark.parametrize("name", ["no-map", "obj-recog-map", "proj-neural-map"])
def test_the_head_widens_by_the_image_embedding_only_with_the_option(name: str) -> None:
    plain, wide = _policy(name, False), _policy(name, True)
    assert plain.found_head is not None and wide.found_head is not None
    assert plain.found_head.in_features == plain.hidden_size
    assert wide.image_encoder is not None
    assert wide.found_head.in_features == wide.hidden_size + wide.image_encoder.out_dim
    assert not plain.found_head_reads_image and wide.found_head_reads_image
    frames = sample_frames(space_for(name), 3, 2, seed=1)
    assert _logit(_run(wide, frames)).shape == _logit(_run(plain, frames)).shape == (3, 2)


def test_the_frame_reaches_found_through_the_new_columns_and_nothing_else() -> None:
    plain, wide = _policy("no-map", False), _policy("no-map", True)
    frames = sample_frames(space_for("no-map"), 4, 3, seed=2)
    # the wide head with the plain one's weights and its image columns zeroed answers as it
    weights = plain.state_dict()
    columns = torch.zeros_like(wide.found_head.weight)  # type: ignore[union-attr]
    columns[:, : plain.hidden_size] = weights["found_head.weight"]
    wide.load_state_dict({**weights, "found_head.weight": columns})
    expected = _run(plain, frames)
    zeroed = _run(wide, frames)
    assert torch.allclose(_logit(zeroed), _logit(expected), atol=1e-6)
    # image columns that read the embedding move FOUND, and only FOUND
    columns[:, plain.hidden_size :] = 0.05
    wide.load_state_dict({**weights, "found_head.weight": columns})
    reading = _run(wide, frames)
    assert not torch.allclose(_logit(reading), _logit(expected), atol=1e-3)
    assert torch.equal(reading.logits, expected.logits)
    assert torch.equal(reading.value, expected.value)


def test_the_option_needs_a_found_head() -> None:
    with pytest.raises(ConfigError, match="--found-head-reads-image .* needs --found-head"):
        Args(found_head_reads_image=True)
    with pytest.raises(ValueError, match="needs a FOUND head"):
        model_spec("no-map").build(space_for("no-map"), found_head_reads_image=True)


def test_a_run_acts_with_the_wide_head_and_resumes_only_with_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(
        tmp_path, room_dataset, frames=128, found_head=1.0, found_head_reads_image=True
    )
    train(args)
    path = tmp_path / "run" / "checkpoint.pt"
    payload = load_checkpoint(path)
    assert payload["args"]["found_head_reads_image"] is True
    policy, _, model = load_policy(path)
    assert model == "no-map" and policy.found_head_reads_image
    assert policy.found_head is not None
    assert torch.equal(policy.found_head.weight, payload["model"]["found_head.weight"])
    assert_resumes_only_with(args, "found_head_reads_image")
