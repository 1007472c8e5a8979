"""The base agent architecture of the paper (§4.1): ``[v_i, v_m, v_g, v_a]`` → GRU → actor, critic.

Every learned agent is a :class:`RecurrentPolicy` with a different :class:`Memory`: the part
that turns a map or an episodic memory into ``v_m``. A memory keeps its per-episode state (a
map, a list of past embeddings) in a dict of tensors whose first dimension is the environment;
**an all-zero state is the empty state**, so the policy clears a finished episode's memory by
multiplying its state by zero.

The same code serves acting (T = 1) and the PPO update, which replays a rollout from the state
saved at its start (recurrent mini-batches). Everything that does not depend on the state (the
CNN over RGB-D, map embeddings) is computed for all T·B frames at once; memories step through
time, and the GRU runs fused over the whole sequence, except beside a memory that reads the GRU
state (FRMQN, EgoMap), with which it advances step by step.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from typing import cast

import numpy as np
import torch
from gymnasium import spaces
from torch import Tensor, nn
from torch.distributions import Categorical

from multion_agents.learned.encoders import ImageEncoder
from multion_agents.learned.found_gate import (
    FOUND,
    FOUND_GATE,
    FOUND_HEAD_PRIOR,
    gate_logit,
    gated_logits,
)
from multion_agents.learned.goal_heads import GOAL_VECTOR, GoalHeads, GoalLosses
from multion_agents.learned.gru import MaskedGRU
from multion_agents.learned.memory import Batch, MapMemory, Memory, State
from multion_client.constants import NUM_ACTIONS, NUM_CATEGORIES

AUTOCAST_DEVICES = ("cpu", "cuda")
"""Devices whose autocast the GRU recurrence turns off (see ``_recurrent``)."""

HIDDEN_SIZE = 768
"""GRU units: ``hidden_size: 768`` in the reference's ``ppo_multinav.yaml`` (saimwani/multiON
``habitat_baselines/config/multinav/ppo_multinav.yaml`` line 45). 512 until issue 31: a
checkpoint's GRU size is read from its weights (:func:`hidden_size_of`)."""
MAX_HIDDEN_SIZE = 4096
GOAL_EMBED_DIM = 32
ACTION_EMBED_DIM = 32
POSE_SENSORS = ("gps", "compass")
POSE_EMBED_DIM = 32
"""Each of GPS and compass (as cos, sin) is embedded by a linear layer to 32 units, as in
habitat-lab's ObjectNav/PointNav baseline (facebookresearch/habitat-lab,
``habitat-baselines/habitat_baselines/rl/ddppo/policy/resnet_policy.py`` l. 487, 520, 718-732).
The reference's MultiON policies do not read them (``--pose-input``, beyond the paper)."""
NO_ACTION = NUM_ACTIONS
"""Index of the "no previous action" embedding, used at an episode's first step."""
IMAGE_FEATURES, IMAGE_EMBEDDING = "image_features", "image_embedding"
"""Frame keys of a frozen image encoder's outputs (``--freeze-vision``), computed once when the
rollout acts and replayed by PPO's update instead of running the encoder once per epoch."""


@dataclass
class PolicyOutput:
    logits: Tensor  # (T, B, A)
    value: Tensor  # (T, B)
    state: State
    auxiliary_loss: Tensor | None
    goal_losses: GoalLosses | None = None
    """The auxiliary goal heads' losses, where the policy has them and ``goal_vector`` is in
    the frames (training); None otherwise."""
    found_logit: Tensor | None = None
    """(T, B): the FOUND head's logit, where the policy has one (``logits`` are then gated)."""


@dataclass
class Replay:
    """A replayed (T, B) sequence: what PPO's loss needs of it."""

    logprob: Tensor  # of the actions taken
    entropy: Tensor
    value: Tensor
    auxiliary_loss: Tensor | None
    logits: Tensor  # (T, B, A), for losses on other actions (imitation)
    goal_losses: GoalLosses | None = None
    found_logit: Tensor | None = None


class RecurrentPolicy(nn.Module):
    """Actor-critic over RGB-D, goal, previous action and a :class:`Memory` (None: no map).

    ``goal_heads``: auxiliary heads on the GRU output trained from the ``goal_vector`` sensor
    (:mod:`.goal_heads`); a training aid that a policy loaded for evaluation is built without.

    ``found_head``: FOUND is decided by a binary head on the GRU output, trained by supervision
    only (``--found-head``, :mod:`.found_supervision`), not by the actor: the policy calls FOUND
    when the head's probability exceeds ``found_gate`` (:data:`FOUND_GATE`, not a weight: an
    evaluation may lower it; :func:`gated_logits`), and otherwise samples a movement from the
    actor. It is part of the agent, kept at evaluation.

    ``found_head_reads_image``: the FOUND head reads the current frame's image embedding
    ``v_i`` beside the GRU output (``--found-head-reads-image``), so its answer need not pass
    through a GRU whose input a map also fills. Part of the agent, kept at evaluation.

    ``pose_input``: the GRU also reads the agent's pose from the episode's start (``gps``,
    ``compass``), each embedded to :data:`POSE_EMBED_DIM` units (``--pose-input``). It is part
    of the agent, kept at evaluation. Memories' queries stay ``[v_i, v_g, v_a]``.

    ``separate_critic``: the critic reads its own GRU (``critic_gru``, state ``critic_hidden``)
    over the actor GRU's inputs, detached, so the value loss trains neither the encoder, the
    memory nor the actor's GRU (``--separate-critic``); a training aid that a policy loaded for
    evaluation is built without (its ``critic`` then reads the actor's GRU, and nothing reads
    it)."""

    def __init__(
        self,
        observation_space: spaces.Dict,
        memory: Memory | None,
        use_rgb: bool = True,
        use_depth: bool = True,
        hidden_size: int = HIDDEN_SIZE,
        goal_heads: bool = False,
        found_head: bool = False,
        pose_input: bool = False,
        separate_critic: bool = False,
        found_head_reads_image: bool = False,
    ) -> None:
        super().__init__()
        if not 1 <= hidden_size <= MAX_HIDDEN_SIZE:
            raise ValueError(f"hidden_size must be in [1, {MAX_HIDDEN_SIZE}], got {hidden_size}")
        self.hidden_size = hidden_size
        self.use_rgb = use_rgb and "rgb" in observation_space.spaces
        self.use_depth = use_depth and "depth" in observation_space.spaces
        self.image_encoder: ImageEncoder | None = None
        image_dim = 0
        if self.use_rgb or self.use_depth:
            key = "rgb" if self.use_rgb else "depth"
            shape = observation_space[key].shape
            assert shape is not None  # an image space is a Box
            size = shape[0]
            self.image_encoder = ImageEncoder(size, self.use_rgb, self.use_depth)
            image_dim = self.image_encoder.out_dim
        self.memory = memory
        self.goal_embedding = nn.Embedding(NUM_CATEGORIES, GOAL_EMBED_DIM)
        self.action_embedding = nn.Embedding(NUM_ACTIONS + 1, ACTION_EMBED_DIM)
        self.query_dim = image_dim + GOAL_EMBED_DIM + ACTION_EMBED_DIM
        memory_dim = memory.out_dim if memory is not None else 0
        self.gps_embedding: nn.Linear | None = None
        self.compass_embedding: nn.Linear | None = None
        pose_dim = 0
        if pose_input:
            self.gps_embedding = nn.Linear(2, POSE_EMBED_DIM)
            self.compass_embedding = nn.Linear(2, POSE_EMBED_DIM)
            pose_dim = 2 * POSE_EMBED_DIM
        gru_input_dim = self.query_dim + pose_dim + memory_dim
        self.gru = nn.GRU(gru_input_dim, hidden_size)
        self.critic_gru = nn.GRU(gru_input_dim, hidden_size) if separate_critic else None
        self.actor = _layer(nn.Linear(hidden_size, NUM_ACTIONS), std=0.01)
        self.critic = _layer(nn.Linear(hidden_size, 1), std=1.0)
        self.goal_heads = GoalHeads(hidden_size) if goal_heads else None
        self.found_head: nn.Linear | None = None
        self.found_gate = FOUND_GATE
        if found_head_reads_image and not (found_head and image_dim):
            raise ValueError("found_head_reads_image needs a FOUND head and an image encoder")
        if found_head:
            found_in = hidden_size + (image_dim if found_head_reads_image else 0)
            self.found_head = _layer(nn.Linear(found_in, 1), std=0.01)
            nn.init.constant_(self.found_head.bias, gate_logit(FOUND_HEAD_PRIOR))

    @property
    def sensors(self) -> tuple[str, ...]:
        """Observation keys read when acting."""
        own = ("rgb",) * self.use_rgb + ("depth",) * self.use_depth + ("goal",)
        pose = POSE_SENSORS if self.pose_input else ()
        extra = self.memory.sensors if self.memory is not None else ()
        return tuple(dict.fromkeys(own + pose + extra))

    @property
    def separate_critic(self) -> bool:
        """Whether the critic reads its own GRU (``--separate-critic``)."""
        return self.critic_gru is not None

    @property
    def found_head_reads_image(self) -> bool:
        """Whether the FOUND head also reads the frame's embedding (a head wider than the GRU)."""
        return self.found_head is not None and self.found_head.in_features > self.hidden_size

    @property
    def pose_input(self) -> bool:
        """Whether the GRU reads the pose (``--pose-input``)."""
        return self.gps_embedding is not None

    @property
    def vision_frozen(self) -> bool:
        """Whether the image encoder takes no gradient (``--freeze-vision``), so its outputs
        for a frame never change during an update and a rollout may keep them."""
        encoder = self.image_encoder
        return encoder is not None and not any(p.requires_grad for p in encoder.parameters())

    def cache_images(self, frames: Batch) -> Batch:
        """``frames`` (B, ...) with the frozen encoder's outputs under :data:`IMAGE_FEATURES`
        and :data:`IMAGE_EMBEDDING`; as they are when the encoder learns."""
        encoder = self.image_encoder
        if encoder is None or not self.vision_frozen:
            return frames
        with torch.no_grad():
            features, embedding = encoder(frames.get("rgb"), frames.get("depth"))
        return {**frames, IMAGE_FEATURES: features, IMAGE_EMBEDDING: embedding}

    @property
    def train_sensors(self) -> tuple[str, ...]:
        """Observation keys needed while training (acting sensors plus supervision)."""
        extra = self.memory.train_sensors if self.memory is not None else ()
        heads = (GOAL_VECTOR,) if self.goal_heads is not None else ()
        return tuple(dict.fromkeys(self.sensors + extra + heads))

    @property
    def device(self) -> torch.device:
        """Where the weights are; states and inputs must be there too."""
        return self.actor.weight.device

    def initial_state(self, batch: int) -> State:
        """The empty state of ``batch`` environments, on the policy's device."""
        device = self.device
        state = {"hidden": torch.zeros(batch, self.hidden_size, device=device)}
        if self.critic_gru is not None:
            state["critic_hidden"] = torch.zeros(batch, self.hidden_size, device=device)
        if self.memory is not None:
            memory = self.memory.initial_state(batch, device)
            state.update({f"memory.{k}": v for k, v in memory.items()})
        return state

    def forward(
        self,
        frames: Batch,
        prev_action: Tensor,
        episode_start: Tensor,
        state: State,
        found_fired: Tensor | None = None,
    ) -> PolicyOutput:
        """Run T steps for B environments. ``frames[k]`` is (T, B, ...); ``prev_action`` (T, B)
        is the action taken before each step (ignored at episode starts); ``episode_start``
        (T, B) is 1 where a new episode begins, which clears the state. ``found_fired`` (T, B):
        with a FOUND head, where its gate was open when the steps were acted (a replay gates
        as the actions were taken); by default where the head says so now."""
        steps, batch = episode_start.shape
        flat = {k: v.reshape(steps * batch, *v.shape[2:]) for k, v in frames.items()}
        starts = episode_start.reshape(-1).bool()
        previous = torch.where(
            starts,
            torch.full_like(starts, NO_ACTION, dtype=torch.long),
            prev_action.reshape(-1).long(),
        )
        parts = []
        image_features, v_i = None, None
        if IMAGE_EMBEDDING in flat:
            if not self.vision_frozen:  # a learning encoder's gradient would be lost
                raise ValueError("cached image features need a frozen image encoder")
            image_features, v_i = flat.pop(IMAGE_FEATURES), flat.pop(IMAGE_EMBEDDING)
            parts.append(v_i)
        elif self.image_encoder is not None:
            image_features, v_i = self.image_encoder(flat.get("rgb"), flat.get("depth"))
            parts.append(v_i)
        parts += [self.goal_embedding(flat["goal"].long()), self.action_embedding(previous)]
        query = torch.cat(parts, dim=1).reshape(steps, batch, -1)
        # the GRU's own inputs: the query, then the pose where it reads it (memories do not)
        pose = self._pose(flat)
        core_in = query if pose is None else torch.cat([query, pose.view(steps, batch, -1)], 2)
        precomputed = self.memory.precompute(flat, image_features) if self.memory else {}
        per_step = {
            k: v.reshape(steps, batch, *v.shape[1:]) for k, v in {**flat, **precomputed}.items()
        }

        memory_state = {k[len("memory.") :]: v for k, v in state.items() if k.startswith("memory.")}
        hidden = state["hidden"]
        if self.memory is None:
            gru_in = core_in
            core, hidden = self._recurrent(gru_in, episode_start, hidden)
        elif self.memory.reads_hidden:
            cores, inputs = [], []
            for t in range(steps):
                keep = 1.0 - episode_start[t].float()
                memory_state = _clear(memory_state, keep)
                hidden = hidden * keep[:, None]
                v_m, memory_state = self.memory.step(
                    {k: v[t] for k, v in per_step.items()},
                    torch.cat([query[t], hidden], dim=1),
                    memory_state,
                )
                inputs.append(torch.cat([core_in[t], v_m], dim=1))
                step_core, hidden = self._recurrent(
                    inputs[-1][None], episode_start[t : t + 1], hidden
                )
                cores.append(step_core[0])
            core, gru_in = torch.stack(cores), torch.stack(inputs)
        else:
            # The memory does not read the GRU state, so its loop runs first, over all steps.
            memory_out = []
            for t in range(steps):
                memory_state = _clear(memory_state, 1.0 - episode_start[t].float())
                frame = {k: v[t] for k, v in per_step.items()}
                if isinstance(self.memory, MapMemory):
                    view, memory_state = self.memory.advance(frame, memory_state)
                    memory_out.append(view)
                else:
                    v_m, memory_state = self.memory.step(frame, query[t], memory_state)
                    memory_out.append(v_m)
            v_ms = torch.stack(memory_out)
            if isinstance(self.memory, MapMemory):  # every step's view read in one batch
                views = v_ms.flatten(0, 1)
                v_ms = self.memory.read(views, {**flat, **precomputed}).view(steps, batch, -1)
            gru_in = torch.cat([core_in, v_ms], dim=2)
            core, hidden = self._recurrent(gru_in, episode_start, hidden)
        new_state = {"hidden": hidden, **{f"memory.{k}": v for k, v in memory_state.items()}}
        critic_core = core
        if self.critic_gru is not None:
            critic_core, new_state["critic_hidden"] = self._recurrent(
                gru_in.detach(), episode_start, state["critic_hidden"], self.critic_gru
            )
        auxiliary = self.memory.auxiliary_loss(flat, precomputed) if self.memory else None
        goal_losses = None
        if self.goal_heads is not None and GOAL_VECTOR in flat:
            goal_losses = self.goal_heads.losses(core.flatten(0, 1), flat[GOAL_VECTOR])
        logits = self.actor(core)
        found_logit = None
        if self.found_head is not None:
            found_in = core
            if self.found_head_reads_image and v_i is not None:
                found_in = torch.cat([core, v_i.view(steps, batch, -1)], dim=2)
            found_logit = self.found_head(found_in).squeeze(-1)
            if found_fired is None:
                fired = found_logit.detach() > gate_logit(self.found_gate)
            else:
                fired = found_fired.bool()
            logits = gated_logits(logits, fired)
        return PolicyOutput(
            logits=logits,
            value=self.critic(critic_core).squeeze(-1),
            state=new_state,
            auxiliary_loss=auxiliary,
            goal_losses=goal_losses,
            found_logit=found_logit,
        )

    def _pose(self, flat: Batch) -> Tensor | None:
        """(T·B, 64): the embedded GPS and compass (as cos, sin), or None without the input."""
        if self.gps_embedding is None or self.compass_embedding is None:
            return None
        heading = flat["compass"].float().reshape(-1, 1)
        compass = torch.cat([heading.cos(), heading.sin()], dim=1)
        gps = self.gps_embedding(flat["gps"].float())
        return torch.cat([gps, self.compass_embedding(compass)], dim=1)

    def _recurrent(
        self, inputs: Tensor, episode_start: Tensor, hidden: Tensor, gru: nn.GRU | None = None
    ) -> tuple[Tensor, Tensor]:
        """A GRU (``nn.GRU``'s equations and weights; the actor's, ``self.gru``, by default)
        over (T, B, D) inputs, its state cleared where episodes start.

        The input projection runs once for all T steps, and :class:`MaskedGRU` forms the
        recurrent weight gradient once (autograd through ``nn.GRU`` or ``nn.GRUCell`` on a CPU
        accumulates a full weight gradient per step, which made PPO updates several times
        slower)."""
        gru = self.gru if gru is None else gru
        # nn.Module types attribute lookups as Tensor | Module; nn.GRU's weights are Parameters
        weight_ih, bias_ih = cast(Tensor, gru.weight_ih_l0), cast(Tensor, gru.bias_ih_l0)
        weight_hh, bias_hh = cast(Tensor, gru.weight_hh_l0), cast(Tensor, gru.bias_hh_l0)
        gates_x = nn.functional.linear(inputs, weight_ih, bias_ih)
        # the recurrence in float32 even under autocast (--mixed-precision): its hand-written
        # backward multiplies with the float32 weight, and bf16 would drift over 128 steps
        gates_x, hidden = gates_x.float(), hidden.float()
        keep = 1.0 - episode_start.to(gates_x.dtype)
        device = gates_x.device.type  # autocast knows cpu and cuda; "meta" (shape checks) not
        off = torch.autocast(device, enabled=False) if device in AUTOCAST_DEVICES else nullcontext()
        with off:
            outputs = MaskedGRU.apply(gates_x, hidden, keep, weight_hh, bias_hh)
        return outputs, outputs[-1]

    # cleanrl-style entry points ---------------------------------------------------------
    def step(
        self, frames: Batch, prev_action: Tensor, episode_start: Tensor, state: State
    ) -> PolicyOutput:
        """One time step for B environments (inputs without the time dimension); the
        output keeps a time dimension of 1."""
        output: PolicyOutput = self(
            {k: v.unsqueeze(0) for k, v in frames.items()},
            prev_action.unsqueeze(0),
            episode_start.unsqueeze(0),
            state,
        )
        return output

    def get_value(
        self, frames: Batch, prev_action: Tensor, episode_start: Tensor, state: State
    ) -> Tensor:
        """V(s) of one step for B environments."""
        return self.step(frames, prev_action, episode_start, state).value[0]

    def get_action_and_value(
        self, frames: Batch, prev_action: Tensor, episode_start: Tensor, state: State
    ) -> tuple[Tensor, Tensor, Tensor, State]:
        """Sample an action for one step: action, log-prob, value, new state."""
        out = self.step(frames, prev_action, episode_start, state)
        dist = Categorical(logits=out.logits[0])
        action = dist.sample()
        return action, dist.log_prob(action), out.value[0], out.state

    def evaluate_actions(
        self,
        frames: Batch,
        prev_action: Tensor,
        episode_start: Tensor,
        state: State,
        actions: Tensor,
    ) -> Replay:
        """Replay a (T, B) sequence: log-probs of ``actions``, entropies, values, auxiliary loss
        and the logits."""
        fired = actions == FOUND if self.found_head is not None else None
        out = self(frames, prev_action, episode_start, state, fired)
        dist = Categorical(logits=out.logits)
        return Replay(
            dist.log_prob(actions),
            dist.entropy(),
            out.value,
            out.auxiliary_loss,
            out.logits,
            out.goal_losses,
            out.found_logit,
        )


def frames_to_tensors(observation: dict[str, np.ndarray], keys: tuple[str, ...]) -> Batch:
    """Batched numpy observations → tensors (uint8 stays uint8: images are scaled in the CNN)."""
    return {k: torch.as_tensor(np.asarray(observation[k])) for k in keys}


def _clear(memory_state: State, keep: Tensor) -> State:
    """Empty the memory of environments whose ``keep`` (B,) is 0 (an all-zero state is empty).
    On the CPU, a step where no episode starts returns the states as they are, not multiplied
    by one (a full pass over ProjNeuralMap's (B, 32, 63, 63) map per step, 6 % of its update);
    elsewhere the test would wait for the device (CUDA) or cannot be read (meta)."""
    if keep.device.type == "cpu" and bool(keep.all()):
        return memory_state
    return {k: v * keep.view(-1, *[1] * (v.dim() - 1)) for k, v in memory_state.items()}


def hidden_size_of(weights: dict[str, Tensor]) -> int:
    """The GRU size of a policy's saved weights (``gru.weight_hh_l0`` is 3H × H)."""
    gate = weights.get("gru.weight_hh_l0")
    if gate is None or gate.dim() != 2:
        raise ValueError("the weights hold no GRU (gru.weight_hh_l0)")
    return int(gate.shape[1])


def _layer(layer: nn.Linear, std: float) -> nn.Linear:
    nn.init.orthogonal_(layer.weight, std)
    nn.init.constant_(layer.bias, 0.0)
    return layer
