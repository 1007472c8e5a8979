"""A trained policy as an :class:`~multion_agents.agent.Agent`, so ``multion eval`` runs it
like any other agent: in the client process, seeing only observations."""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import torch

from multion_agents.agent import Agent, AgentError, ConfigOverrides, Observation
from multion_agents.learned.checkpoint import load_policy
from multion_agents.learned.memory import State
from multion_agents.learned.policy import RecurrentPolicy, frames_to_tensors


class LearnedAgent(Agent):
    """Acts with a :class:`RecurrentPolicy`; samples from its action distribution (with the
    agent's own random stream) or, when ``deterministic``, takes the most likely action."""

    policy: ClassVar[RecurrentPolicy | None] = None
    model: ClassVar[str] = ""
    """The registry name of the policy's model (``multion_agents.learned.models``)."""
    deterministic: ClassVar[bool] = False

    def __init__(self, seed: int = 0) -> None:
        super().__init__(seed)
        if self.policy is None:
            raise TypeError("LearnedAgent needs a policy: use learned_agent_class(checkpoint)")
        self._state: State = {}
        self._prev_action = 0
        self._start = True

    def configure(self, config: dict[str, Any]) -> None:
        """Refuses an environment that differs from the checkpoint's in a field that shapes the
        observations (``camera``, ``maps``: what ``config_overrides`` holds) or in its goal set
        (``task.goal_set``, an override only when it is not the default ``colours``)."""
        super().configure(config)
        wrong = []
        goal_set = config.get("task", {}).get("goal_set", "colours")
        trained = self.config_overrides.get("task", {}).get("goal_set", "colours")
        if goal_set != trained:
            wrong.append(f"task.goal_set={goal_set!r} (trained with {trained!r})")
        wrong += [
            f"{section}.{key}={config.get(section, {}).get(key)!r} (trained with {value!r})"
            for section, values in self.config_overrides.items()
            for key, value in values.items()
            if config.get(section, {}).get(key) != value and key != "goal_set"
        ]
        if wrong:
            raise AgentError(
                f"this {self.model or 'learned'} checkpoint cannot act in this environment: "
                + ", ".join(wrong)
                + "; leave these fields as the checkpoint recorded them"
            )

    def recorded_settings(self) -> dict[str, Any]:
        """A FOUND head's gate (``multion eval --found-gate``); nothing for other policies."""
        if self.policy is None or self.policy.found_head is None:
            return {}
        return {"found_gate": self.policy.found_gate}

    def reset(self) -> None:
        assert self.policy is not None
        self._state = self.policy.initial_state(1)
        self._prev_action = 0
        self._start = True

    @torch.no_grad()
    def act(self, observation: Observation) -> int:
        assert self.policy is not None
        device = self.policy.device
        out = self.policy.step(
            {
                k: v.unsqueeze(0).to(device)
                for k, v in frames_to_tensors(observation, self.policy.sensors).items()
            },
            torch.tensor([self._prev_action], device=device),
            torch.tensor([float(self._start)], device=device),
            self._state,
        )
        self._state, self._start = out.state, False
        logits = out.logits[0, 0].double().cpu()
        if self.deterministic:
            action = int(logits.argmax())
        else:
            probs = torch.softmax(logits, 0).numpy()
            action = int(self.rng.choice(len(probs), p=probs / probs.sum()))
        self._prev_action = action
        return action


def agent_class_for_policy(
    policy: RecurrentPolicy,
    config_overrides: ConfigOverrides,
    deterministic: bool = False,
    model: str = "",
) -> type[LearnedAgent]:
    """An Agent class bound to ``policy`` (the evaluator builds agents from classes)."""
    policy.eval()
    attributes: dict[str, Any] = {
        "policy": policy,
        "model": model,
        "deterministic": deterministic,
        "sensors": policy.sensors,
        "config_overrides": config_overrides,
    }
    return type(f"Learned[{model or 'policy'}]", (LearnedAgent,), attributes)


def learned_agent_class(
    checkpoint: str | Path, deterministic: bool = False, found_gate: float | None = None
) -> type[LearnedAgent]:
    """The Agent class of a training checkpoint (its model, weights and camera size), with its
    FOUND head's gate at ``found_gate`` (None: the policy's own)."""
    policy, overrides, model = load_policy(checkpoint)
    if found_gate is not None:
        if policy.found_head is None:
            raise AgentError(
                f"--found-gate {found_gate:g}: {checkpoint} has no FOUND head (it was trained "
                "without --found-head; its actor calls FOUND)"
            )
        policy.found_gate = found_gate
    return agent_class_for_policy(policy, overrides, deterministic, model)
