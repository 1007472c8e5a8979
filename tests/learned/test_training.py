"""PPO / DD-PPO training: every model trains, GAE by hand, resume, DD-PPO ranks in sync, eval."""

from __future__ import annotations

import copy
import csv
import dataclasses
import math
import os
import re
import socket
from pathlib import Path

import pytest
import torch
import torch.multiprocessing as mp
from rollouts import SIZE, random_rollout, sample_frames, space_for, tiny_args

from multion.config.codec import env_config_from_dict
from multion_agents.learned.checkpoint import (
    CheckpointError,
    load_checkpoint,
    restore_random_states,
)
from multion_agents.learned.models import MODELS
from multion_agents.learned.ppo import (
    Args,
    gru_gradient_norms,
    ppo_terms,
    ppo_update,
    schedule,
    set_found_prior,
)
from multion_agents.learned.rollout import Rollout, compute_gae
from multion_agents.learned.training_run import save_run_checkpoint, train


@pytest.mark.parametrize("name", list(MODELS))
def test_every_model_runs_forward_and_backward_on_env_shapes(name: str) -> None:
    torch.manual_seed(0)
    space = space_for(name)
    policy = MODELS[name].build(space)
    steps, batch = 3, 2
    frames = sample_frames(space, steps, batch)
    actions = torch.randint(0, 4, (steps, batch))
    starts = torch.tensor([[1.0, 1.0], [0.0, 0.0], [0.0, 1.0]])
    replay = policy.evaluate_actions(frames, actions, starts, policy.initial_state(batch), actions)
    logprob, entropy, value, aux = (
        replay.logprob,
        replay.entropy,
        replay.value,
        replay.auxiliary_loss,
    )
    assert logprob.shape == entropy.shape == value.shape == (steps, batch)
    loss = -logprob.mean() + value.pow(2).mean() + (aux if aux is not None else 0.0)
    loss.backward()
    assert torch.isfinite(loss)
    assert policy.actor.weight.grad.abs().sum() > 0
    assert policy.goal_embedding.weight.grad.abs().sum() > 0
    if policy.image_encoder is not None:
        assert policy.image_encoder.embed[1].weight.grad.abs().sum() > 0
    if policy.memory is not None:  # the memory's parameters learn from the PPO loss
        grads = [p.grad for p in policy.memory.parameters() if p.grad is not None]
        assert grads and sum(float(g.abs().sum()) for g in grads) > 0


def test_schedule_follows_the_reference_by_default_and_can_be_switched_off() -> None:
    args = Args(learning_rate=1e-3, clip=0.2)
    assert not args.normalize_advantages and args.envs == 16
    assert schedule(args, 0, 4) == pytest.approx((1e-3, 0.2))
    assert schedule(args, 3, 4) == pytest.approx((0.25e-3, 0.05))
    assert schedule(args, 9, 4) == (0.0, 0.0)  # never negative
    fixed = Args(learning_rate=1e-3, clip=0.2, lr_decay=False, clip_decay=False)
    assert schedule(fixed, 3, 4) == pytest.approx((1e-3, 0.2))


def test_advantages_are_normalised_only_when_asked(monkeypatch: pytest.MonkeyPatch) -> None:
    """ppo_update hands the loss the raw advantages by default (the reference), normalised ones
    with ``normalize_advantages``, and logs the raw ones' spread either way."""
    import multion_agents.learned.ppo as ppo

    seen: list[torch.Tensor] = []

    def spy(policy, batch, clip, args, found):
        seen.append(batch.advantages)
        return ppo_terms(policy, batch, clip, args, found)

    monkeypatch.setattr(ppo, "ppo_terms", spy)
    space = space_for("no-map")
    torch.manual_seed(0)
    policy = MODELS["no-map"].build(space)
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-4)
    rollout = random_rollout(space, 0)
    rollout.initial_state = policy.initial_state(2)
    rollout.advantages = rollout.advantages * 10 + 5
    raw = ppo_update(policy, optimizer, rollout, Args(minibatches=1, epochs=1))
    # the one mini-batch holds every environment, in a random order
    torch.testing.assert_close(seen[-1].flatten().sort()[0], rollout.advantages.flatten().sort()[0])
    normalised = ppo_update(
        policy, optimizer, rollout, Args(minibatches=1, epochs=1, normalize_advantages=True)
    )
    assert abs(float(seen[-1].mean())) < 1e-5 and float(seen[-1].std()) == pytest.approx(
        1, rel=1e-4
    )
    # both log the spread of the advantages as GAE gave them, before any normalising
    expected = float(rollout.advantages.std())
    assert expected > 1
    assert raw["advantage_std"] == normalised["advantage_std"] == pytest.approx(expected)


def test_measuring_the_gradients_leaves_the_update_as_it_was() -> None:
    space = space_for("no-map")
    torch.manual_seed(0)
    policy = MODELS["no-map"].build(space)
    twin = copy.deepcopy(policy)
    rollout = random_rollout(space, 0)
    rollout.initial_state = policy.initial_state(2)
    updated = {}
    for measure, model in ((False, policy), (True, twin)):
        optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)
        torch.manual_seed(1)
        updated[measure] = ppo_update(model, optimizer, rollout, Args(), measure_gradients=measure)
    for (name, weight), other in zip(
        policy.state_dict().items(), twin.state_dict().values(), strict=True
    ):
        torch.testing.assert_close(weight, other, rtol=0, atol=0, msg=name)
    assert "gru_gradient_policy" not in updated[False]
    assert updated[True]["gru_gradient_policy"] > 0 and updated[True]["gru_gradient_value"] > 0


def test_each_terms_gradient_norm_is_its_own() -> None:
    """Without advantages or entropy bonus the policy term teaches nothing; the value term's
    norm scales with its weight."""
    space = space_for("no-map")
    torch.manual_seed(0)
    policy = MODELS["no-map"].build(space)
    rollout = random_rollout(space, 0)
    rollout.initial_state = policy.initial_state(2)
    rollout.advantages = torch.zeros_like(rollout.advantages)
    norms = []
    for value_coef in (0.5, 1.0):
        args = Args(entropy_coef=0.0, value_coef=value_coef, minibatches=1, epochs=1)
        terms, _ = ppo_terms(policy, rollout, 0.2, args)
        norms.append(gru_gradient_norms(policy, terms))
    assert norms[0]["gru_gradient_policy"] == 0.0
    assert norms[1]["gru_gradient_value"] == pytest.approx(2 * norms[0]["gru_gradient_value"])
    assert set(norms[0]) == {"gru_gradient_policy", "gru_gradient_value"}


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_training_runs_end_to_end_on_cuda(tmp_path: Path, room_dataset: Path) -> None:
    summary = train(tiny_args(tmp_path, room_dataset, agent="ego-map", device="cuda"))
    assert summary["frames"] == 192 and math.isfinite(summary["policy_loss"])


def test_a_cuda_device_without_a_gpu_is_a_clear_error(tmp_path: Path, room_dataset: Path) -> None:
    if torch.cuda.is_available():
        pytest.skip("a GPU is present")
    with pytest.raises(ValueError, match="no CUDA GPU"):
        train(tiny_args(tmp_path, room_dataset, device="cuda"))


def test_gae_matches_hand_computation() -> None:
    rewards = torch.tensor([[1.0], [0.0], [2.0]])
    values = torch.tensor([[0.5], [0.2], [0.1]])
    dones = torch.tensor([[0.0], [1.0], [0.0]])  # the episode ends after step 1
    empty = torch.zeros(3, 1)
    rollout = Rollout({}, empty, empty, empty, empty, values, rewards, dones, {})
    gamma, lam, next_value = 0.9, 0.8, torch.tensor([0.3])
    compute_gae(rollout, next_value, gamma, lam)
    d2 = 2.0 + gamma * 0.3 - 0.1
    d1 = 0.0 - 0.2  # no bootstrap across the episode end
    d0 = 1.0 + gamma * 0.2 - 0.5
    expected = [d0 + gamma * lam * d1, d1, d2]
    assert rollout.advantages[:, 0].tolist() == pytest.approx(expected)
    assert rollout.returns[:, 0].tolist() == pytest.approx(
        [e + v for e, v in zip(expected, [0.5, 0.2, 0.1], strict=True)]
    )


@pytest.mark.parametrize("name", list(MODELS))
def test_every_model_trains_a_few_hundred_frames(
    name: str, tmp_path: Path, room_dataset: Path
) -> None:
    args = tiny_args(tmp_path, room_dataset, agent=name, update_threads=2)
    summary = train(args)
    assert summary["frames"] == 192 and summary["update"] == 3
    assert torch.get_num_threads() == args.threads  # the update's threads are given back
    for key in ("policy_loss", "value_loss", "entropy"):
        assert math.isfinite(summary[key])
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert [int(r["frames"]) for r in rows] == [64, 128, 192]
    # the reference schedule: learning rate and clip range decay linearly over the 3 updates
    # (progress.csv keeps 3 significant digits)
    assert [float(r["learning_rate"]) for r in rows] == pytest.approx(
        [args.learning_rate * f for f in (1, 2 / 3, 1 / 3)], rel=1e-2
    )
    assert [float(r["clip"]) for r in rows] == pytest.approx(
        [args.clip * f for f in (1, 2 / 3, 1 / 3)], rel=1e-2
    )
    payload = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    assert payload["agent"] == name and payload["update"] == 3
    fresh = copy.deepcopy(MODELS[name].build(space_for(name)))
    changed = [
        not torch.equal(fresh.state_dict()[k], v)
        for k, v in payload["model"].items()
        if v.is_floating_point()
    ]
    assert any(changed)  # the optimiser moved the weights


def test_resume_reproduces_the_next_update_exactly(tmp_path: Path) -> None:
    """Optimiser moments and random states survive a checkpoint: the update after a resume is
    bit-identical to the one an uninterrupted run makes on the same rollout."""
    name, args = "oracle-map", Args(minibatches=2)
    space = space_for(name)
    torch.manual_seed(3)
    policy = MODELS[name].build(space)
    policy_state = policy.initial_state(2)
    optimizer = torch.optim.Adam(policy.parameters(), lr=args.learning_rate, eps=1e-5)
    first, second = random_rollout(space, 1), random_rollout(space, 2)
    for rollout in (first, second):
        rollout.initial_state = policy_state
    ppo_update(policy, optimizer, first, args)
    path = tmp_path / "checkpoint.pt"
    camera = {"camera": {"width": SIZE, "height": SIZE}}
    save_run_checkpoint(path, policy, optimizer, args, env_config_from_dict(camera), 1, 12)
    ppo_update(policy, optimizer, second, args)
    uninterrupted = copy.deepcopy(policy.state_dict())

    torch.manual_seed(99)  # a different process state before loading
    resumed = MODELS[name].build(space)
    resumed_optimizer = torch.optim.Adam(resumed.parameters(), lr=args.learning_rate, eps=1e-5)
    payload = load_checkpoint(path)
    resumed.load_state_dict(payload["model"])
    resumed_optimizer.load_state_dict(payload["optimizer"])
    restore_random_states(payload)
    ppo_update(resumed, resumed_optimizer, second, args)
    for key, value in resumed.state_dict().items():
        assert torch.equal(value, uninterrupted[key]), key


def test_resume_continues_the_run_and_refuses_another_agent(
    tmp_path: Path, room_dataset: Path
) -> None:
    train(tiny_args(tmp_path, room_dataset, frames=64))
    summary = train(tiny_args(tmp_path, room_dataset, frames=128, resume=True))
    assert summary["update"] == 2 and summary["frames"] == 128
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert [int(r["update"]) for r in rows] == [1, 2]
    with pytest.raises(CheckpointError, match="no-map"):
        train(tiny_args(tmp_path, room_dataset, agent="no-map", frames=192, resume=True))
    # resuming a run that already holds its frames trains nothing and says so (a resumable
    # script runs `multion train --resume` again after an interruption during its evaluation)
    again = train(tiny_args(tmp_path, room_dataset, frames=128, resume=True))
    assert again["frames"] == 128 and "fps" not in again
    assert len(list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))) == 2


def test_resume_drops_the_updates_logged_after_the_checkpoint(
    tmp_path: Path, room_dataset: Path
) -> None:
    """A run stopped past its last checkpoint has logged updates its resumption makes again:
    the log keeps each update once, the resumed one."""
    train(tiny_args(tmp_path, room_dataset, frames=64))  # update 1, checkpointed
    run = tmp_path / "run"
    for name in ("progress", "eval"):
        path = run / f"{name}.csv"
        if not path.exists():
            path.write_text("frames,update,success,progress,spl,ppl\n64,1,1,1,0.5,0.5\n")
        rows = list(csv.DictReader(path.open()))
        orphan = {**rows[-1], "update": "2", "frames": "-1"}  # logged, then interrupted
        with path.open("a", newline="") as handle:
            csv.DictWriter(handle, list(rows[0])).writerow(orphan)
    train(tiny_args(tmp_path, room_dataset, frames=128, resume=True))
    rows = list(csv.DictReader((run / "progress.csv").open()))
    assert [(int(r["update"]), int(r["frames"])) for r in rows] == [(1, 64), (2, 128)]
    evals = list(csv.DictReader((run / "eval.csv").open()))
    assert all(int(r["update"]) <= 1 for r in evals)
    assert sorted(p.name for p in run.glob("*.csv")) == ["eval.csv", "progress.csv"]
    assert not [p for p in run.iterdir() if p.name.startswith(".")]  # no temporary left


def test_a_corrupt_checkpoint_is_refused_with_its_path(tmp_path: Path) -> None:
    path = tmp_path / "checkpoint.pt"
    path.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="checkpoint.pt"):
        load_checkpoint(path)


def _ddppo_rank(rank: int, port: int, out: str, dataset: str, results: str) -> None:
    os.environ.update(
        MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank), WORLD_SIZE="2"
    )
    args = tiny_args(Path(out), Path(dataset), frames=256, seed=4)
    summary = train(args)
    Path(results, f"rank{rank}.txt").write_text(f"{summary['weights_sha256']} {summary['frames']}")
    torch.distributed.destroy_process_group()


def test_ddppo_two_cpu_ranks_keep_identical_weights(tmp_path: Path, room_dataset: Path) -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    results = tmp_path / "results"
    results.mkdir()
    mp.start_processes(
        _ddppo_rank,
        args=(port, str(tmp_path), str(room_dataset), str(results)),
        nprocs=2,
        start_method="spawn",
    )
    rank0 = (results / "rank0.txt").read_text().split()
    rank1 = (results / "rank1.txt").read_text().split()
    assert rank0 == rank1  # same weights after every all-reduced update, same frame count
    assert int(rank0[1]) == 256  # 2 ranks × 2 envs × 32 steps per update, 2 updates
    torch.manual_seed(4)
    initial = MODELS["oracle-map"].build(space_for("oracle-map"))
    from multion_agents.learned.distributed import weights_digest

    assert weights_digest(initial) != rank0[0]
    assert (tmp_path / "run" / "checkpoint.pt").is_file()  # written by rank 0 only


@pytest.mark.parametrize("name", ["oracle-map", "frmqn", "obj-recog-map", "proj-neural-map"])
def test_replaying_a_rollout_reproduces_its_log_probs_and_values(name: str) -> None:
    """The PPO update's sequence replay computes exactly what acting step by step computed
    (the same states, resets and previous actions), so the first ratio is 1."""
    torch.manual_seed(1)
    space = space_for(name)
    policy = MODELS[name].build(space)
    steps, batch = 6, 2
    frames = sample_frames(space, steps, batch, seed=3)
    starts = torch.zeros(steps, batch)
    starts[0] = 1.0
    starts[3, 0] = 1.0
    state = policy.initial_state(batch)
    initial = {k: v.clone() for k, v in state.items()}
    prev = torch.zeros(batch, dtype=torch.long)
    actions, logprobs, values, prevs = [], [], [], []
    with torch.no_grad():
        for t in range(steps):
            frame = {k: v[t] for k, v in frames.items()}
            action, logprob, value, state = policy.get_action_and_value(
                frame, prev, starts[t], state
            )
            prevs.append(prev)
            actions.append(action)
            logprobs.append(logprob)
            values.append(value)
            prev = action
        replay = policy.evaluate_actions(
            frames, torch.stack(prevs), starts, initial, torch.stack(actions)
        )
    assert torch.allclose(replay.logprob, torch.stack(logprobs), atol=1e-5)
    assert torch.allclose(replay.value, torch.stack(values), atol=1e-5)


def test_a_checkpoint_is_evaluated_through_the_eval_path(
    tmp_path: Path, room_dataset: Path
) -> None:
    from multion_agents.agent import AgentError
    from multion_agents.evaluate import EvalSettings, evaluate

    train(tiny_args(tmp_path, room_dataset, frames=64))
    checkpoint = str(tmp_path / "run" / "checkpoint.pt")
    settings = EvalSettings(
        agent="oracle-map",
        num_goals=1,
        split="train",
        episodes=2,
        in_process=True,
        dataset=str(room_dataset),
        max_steps=20,
        checkpoint=checkpoint,
        deterministic=True,
    )
    first, second = evaluate(settings, progress=False), evaluate(settings, progress=False)
    assert len(first.records) == 2
    camera = first.config["camera"]  # the trained camera, every field but the renderer
    assert camera["width"] == camera["height"] == SIZE and camera["hfov_deg"] == 79.0
    assert "renderer" not in camera  # the evaluating machine picks its own
    assert [r.metrics for r in first.records] == [r.metrics for r in second.records]
    with pytest.raises(AgentError, match="holds a 'oracle-map' agent"):
        evaluate(
            EvalSettings(
                agent="no-map", num_goals=1, checkpoint=checkpoint, dataset=str(room_dataset)
            ),
            progress=False,
        )


def test_found_prior_sets_the_untrained_policys_found_probability() -> None:
    space = space_for("oracle-map")
    torch.manual_seed(0)
    policy = MODELS["oracle-map"].build(space)
    set_found_prior(policy, 0.02)
    frames = sample_frames(space, steps=1, batch=64)
    with torch.no_grad():
        out = policy(frames, torch.zeros(1, 64), torch.ones(1, 64), policy.initial_state(64))
    probs = torch.softmax(out.logits[0], dim=-1)
    assert torch.allclose(probs[:, 0], torch.full((64,), 0.02), atol=0.005)
    assert torch.allclose(probs[:, 1:], torch.full((64, 3), 0.98 / 3), atol=0.01)
    for bad in (0.0, 1.0, -0.1):
        with pytest.raises(ValueError, match="found_prior"):
            set_found_prior(policy, bad)


def test_train_cli_rejects_a_bad_found_prior(tmp_path: Path, capsys) -> None:
    from multion_agents.cli import main

    code = main(["train", "--found-prior", "1.5", "--frames", "64", "--out", str(tmp_path)])
    assert code == 2
    assert "found_prior must be in (0, 1), got 1.5" in capsys.readouterr().err
    assert not (tmp_path / "checkpoint.pt").exists()


@pytest.mark.parametrize("recipe", ["default", "v3"])
def test_training_bench_measures_both_rates_in_one_run(capsys, recipe: str) -> None:
    from multion_agents.bench.train import bench_settings, run_train_bench

    agent = "no-map" if recipe == "default" else None  # v3: the recipe's oracle-map
    # v3: one row per number of envs, the envs sharing processes (2 per process)
    envs, per_process = ((2,), 1) if recipe == "default" else ((2, 3), 2)
    settings = bench_settings(recipe, agent, 36, envs, 2, "cpu", per_process)
    results = run_train_bench(settings)
    assert results is not None and list(results) == list(envs)
    for result in results.values():
        assert result["bare_fps"] > 0 and result["train_fps"] > 0
        assert result["ratio"] == pytest.approx(result["train_fps"] / result["bare_fps"])
        shares = [result[f"{k}_share"] for k in ("sim", "act", "update")]
        assert all(0 < s < 1 for s in shares) and sum(shares) <= 1.0 + 1e-6
        assert result["learner_ms_per_frame"] > 0
    out = capsys.readouterr().out
    assert "ratio train / bare" in out
    rows = [line.split()[0] for line in out.splitlines() if line[:5].strip().isdigit()]
    assert rows == [str(n) for n in envs]
    if recipe == "v3":
        assert "oracle-map" in out and "online train episodes" in out
        assert "(2 per process)" in out


def test_the_training_bench_names_a_bad_env_count_or_update_count(capsys) -> None:
    from multion_agents.cli import main

    assert main(["bench", "--only", "train", "--train-envs", "8,x"]) == 2
    assert "--train-envs '8,x': comma-separated whole numbers" in capsys.readouterr().err
    assert main(["bench", "--only", "train", "--train-updates", "1"]) == 2
    assert "--train-updates 1: at least 2" in capsys.readouterr().err


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the message of a machine without one")
def test_the_cuda_training_bench_says_plainly_it_needs_a_gpu(capsys) -> None:
    from multion_agents.cli import main

    assert main(["bench", "--only", "train", "--device", "cuda"]) == 2
    assert "needs a CUDA GPU" in capsys.readouterr().out


def test_a_curriculum_trains_on_near_goals_first_then_on_the_tasks_own(tmp_path: Path) -> None:
    args = tiny_args(tmp_path, Path("unused"), frames=256, curriculum=((128, 3.0),))
    args = dataclasses.replace(args, dataset=None)  # sampled online from the train houses
    train(args)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert [float(r["max_geodesic"]) for r in rows] == [3.0, 3.0, 20.0, 20.0]
    # the checkpoint keeps the task's own config: a resume or an evaluation never sees the stage
    assert load_checkpoint(tmp_path / "run" / "checkpoint.pt")["env_config"][
        "online_max_geodesic"
    ] == pytest.approx(20.0)


@pytest.mark.parametrize(
    ("stages", "message"),
    [
        (["240000:4", "100000:10"], "increasing frame counts > 0, got \\[240000, 100000\\]"),
        (["0:4"], "increasing frame counts > 0"),
        (["240000:1"], "online_max_geodesic = 1.0 is out of range: allowed \\[2, 20\\]"),
        (["240000:25"], "online_max_geodesic = 25.0 is out of range"),
        (["240000"], "'240000' is not FRAMES:METRES"),
        (["4:x"], "'4:x' is not FRAMES:METRES"),
    ],
)
def test_train_cli_rejects_a_bad_curriculum(
    tmp_path: Path, capsys, stages: list[str], message: str
) -> None:
    from multion_agents.cli import main

    flags = [arg for stage in stages for arg in ("--curriculum", stage)]
    code = main(["train", *flags, "--frames", "64", "--out", str(tmp_path)])
    assert code == 2
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "checkpoint.pt").exists()


def test_a_curriculum_needs_online_episodes(tmp_path: Path, room_dataset: Path) -> None:
    with pytest.raises(ValueError, match="cannot be used with --dataset"):
        train(tiny_args(tmp_path, room_dataset, curriculum=((128, 3.0),)))


def test_the_gru_size_is_a_setting_and_a_resume_must_keep_it(
    tmp_path: Path, room_dataset: Path
) -> None:
    from multion_agents.learned.checkpoint import CheckpointError, load_checkpoint
    from multion_agents.learned.policy import hidden_size_of

    args = tiny_args(tmp_path, room_dataset, frames=64, hidden_size=64)
    train(args)
    assert hidden_size_of(load_checkpoint(tmp_path / "run" / "checkpoint.pt")["model"]) == 64
    with pytest.raises(CheckpointError, match="GRU of 64 units; this run asks for 768"):
        train(tiny_args(tmp_path, room_dataset, frames=128, resume=True))
    train(tiny_args(tmp_path, room_dataset, frames=128, resume=True, hidden_size=64))
    with pytest.raises(ValueError, match=r"--hidden-size must be in \[1, 4096\], got 0"):
        train(tiny_args(tmp_path / "zero", room_dataset, hidden_size=0))
