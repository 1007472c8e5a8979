"""The learned agents' memories: FRMQN, SMT, ObjRecogMap, ProjNeuralMap, EgoMap."""

from __future__ import annotations

import math

import pytest
import torch

from multion.config.sim import CameraConfig
from multion.config.task import EnvConfig
from multion.task.spaces import build_observation_space
from multion_agents.learned import map_ops
from multion_agents.learned.episodic import FRMQN, SMT, masked_attention
from multion_agents.learned.learned_maps import EgoMap, ObjRecogMap, recognition_label
from multion_agents.learned.memory import Memory
from multion_agents.learned.models import model_spec
from multion_agents.learned.policy import HIDDEN_SIZE, RecurrentPolicy

NEW_MODELS = [
    "frmqn",
    "smt",
    "obj-recog-map",
    "dynamic-obj-recog-map",
    "proj-neural-map",
    "ego-map",
]
SIZE = 64
G = map_ops.GLOBAL_SIZE
C0 = G // 2
GEOMETRY = map_ops.MapGeometry(
    cell_size=0.8, crop_size=25, hfov_deg=79.0, min_depth=0.5, max_depth=5.0, normalized_depth=True
)
CELL = GEOMETRY.cell_size


def _space(name: str):
    spec = model_spec(name)
    camera = CameraConfig(width=SIZE, height=SIZE)
    return spec, build_observation_space(EnvConfig(sensors=spec.train_sensors, camera=camera))


def _frames(space, steps: int, batch: int, seed: int = 0) -> dict[str, torch.Tensor]:
    gen = torch.Generator().manual_seed(seed)
    frames = {}
    for key in space.spaces:
        if key == "rgb":
            frames[key] = torch.randint(0, 256, (steps, batch, SIZE, SIZE, 3), generator=gen).to(
                torch.uint8
            )
        elif key == "depth":
            frames[key] = torch.rand(steps, batch, SIZE, SIZE, 1, generator=gen)
        elif key == "goal":
            frames[key] = torch.randint(0, 8, (steps, batch), generator=gen)
        elif key == "gps":
            # a walk around the start, 0.25 m steps
            frames[key] = (torch.randn(steps, batch, 2, generator=gen) * 0.25).cumsum(0)
        elif key == "compass":
            frames[key] = (torch.rand(steps, batch, 1, generator=gen) * 2 - 1) * math.pi
        elif key == "goal_mask":
            mask = torch.zeros(steps, batch, SIZE, SIZE, dtype=torch.uint8)
            mask[:, :, 20:40, 10:20] = torch.randint(0, 9, (steps, batch, 1, 1), generator=gen).to(
                torch.uint8
            )
            frames[key] = mask
        else:
            raise AssertionError(f"unexpected sensor {key}")
    return frames


@pytest.mark.parametrize("name", NEW_MODELS)
def test_forward_backward_reaches_memory_parameters(name: str) -> None:
    torch.manual_seed(0)
    spec, space = _space(name)
    policy = spec.build(space)
    steps, batch = 4, 2
    frames = _frames(space, steps, batch)
    starts = torch.zeros(steps, batch)
    starts[0] = 1
    out = policy(frames, torch.randint(0, 4, (steps, batch)), starts, policy.initial_state(batch))
    assert out.logits.shape == (steps, batch, 4) and out.value.shape == (steps, batch)
    loss = out.logits.logsumexp(-1).sum() + out.value.sum()
    if "obj-recog" in name:
        assert out.auxiliary_loss is not None and torch.isfinite(out.auxiliary_loss)
        loss = loss + out.auxiliary_loss
    else:
        assert out.auxiliary_loss is None
    loss.backward()
    assert policy.memory is not None
    for pname, param in policy.memory.named_parameters():
        assert param.grad is not None, pname
        assert torch.isfinite(param.grad).all(), pname
        assert param.grad.abs().sum() > 0, pname
    for key, value in out.state.items():
        assert torch.isfinite(value).all(), key
    # the map memories' gradients reach the image CNN through the map too
    assert policy.image_encoder is not None
    assert policy.image_encoder.features[0].weight.grad.abs().sum() > 0


@pytest.mark.parametrize("name", NEW_MODELS)
def test_reset_mid_sequence_equals_fresh_run(name: str) -> None:
    torch.manual_seed(1)
    spec, space = _space(name)
    policy = spec.build(space)
    steps, batch, reset = 6, 2, 3
    with torch.no_grad():
        warm = _frames(space, steps, batch, seed=5)
        starts = torch.zeros(steps, batch)
        starts[0] = 1
        state = policy(
            warm, torch.randint(0, 4, (steps, batch)), starts, policy.initial_state(batch)
        ).state
        assert any(v.abs().sum() > 0 for k, v in state.items() if k.startswith("memory."))

        frames = _frames(space, steps, batch, seed=6)
        actions = torch.randint(0, 4, (steps, batch))
        starts = torch.zeros(steps, batch)
        starts[reset, 0] = 1  # env 0 starts a new episode at t = 3, env 1 continues
        full = policy(frames, actions, starts, state)
        tail = {k: v[reset:] for k, v in frames.items()}
        fresh_starts = torch.zeros(steps - reset, batch)
        fresh_starts[0] = 1
        fresh = policy(tail, actions[reset:], fresh_starts, policy.initial_state(batch))
    torch.testing.assert_close(full.logits[reset:, 0], fresh.logits[:, 0], atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(full.value[reset:, 0], fresh.value[:, 0], atol=1e-5, rtol=1e-5)
    assert not torch.allclose(full.logits[reset:, 1], fresh.logits[:, 1])


# episodic memories ------------------------------------------------------------------------


def test_frmqn_empty_memory_reads_zeros() -> None:
    memory = FRMQN(observation_dim=10, hidden_dim=5, memory_size=4, key_dim=6, out_dim=8)
    state = memory.initial_state(2, torch.device("cpu"))
    read, new_state = memory.step({}, torch.randn(2, 15), state)
    assert torch.equal(read, torch.zeros(2, 8))
    assert new_state["valid"].sum(1).tolist() == [1.0, 1.0]
    assert new_state["count"].tolist() == [[1.0], [1.0]]


def test_masked_attention_ignores_empty_slots() -> None:
    keys, values = torch.randn(2, 5, 4), torch.randn(2, 5, 3)
    valid = torch.zeros(2, 5)
    valid[0, 2] = 1.0
    read = masked_attention(torch.randn(2, 4), keys, values, valid)
    torch.testing.assert_close(read[0], values[0, 2])
    assert torch.equal(read[1], torch.zeros(3))


def test_frmqn_ring_buffer_keeps_the_last_m() -> None:
    memory = FRMQN(observation_dim=3, hidden_dim=2, memory_size=4, key_dim=2, out_dim=2)
    state = memory.initial_state(1, torch.device("cpu"))
    for _ in range(6):
        _, state = memory.step({}, torch.randn(1, 5), state)
    assert state["count"].item() == 6 and state["valid"].sum().item() == 4


def test_smt_empty_memory_has_no_nan() -> None:
    memory = SMT(query_dim=10, memory_size=4, dim=8, heads=2, out_dim=6)
    current = torch.randn(2, 8, requires_grad=True)
    read = memory.read(current, torch.zeros(2, 4, 8), torch.zeros(2, 4))
    assert torch.equal(read, torch.zeros(2, 8))
    read.sum().backward()
    assert all(torch.isfinite(p.grad).all() for p in memory.parameters() if p.grad is not None)
    # a partly filled memory: slots never written do not change the read
    memory_items, valid = torch.randn(1, 4, 8), torch.tensor([[1.0, 1.0, 0.0, 0.0]])
    first = memory.read(current[:1], memory_items, valid)
    memory_items[0, 2:] = torch.randn(2, 8)
    torch.testing.assert_close(memory.read(current[:1], memory_items, valid), first)


# ObjRecogMap ----------------------------------------------------------------------------


def _normalised(metres: float) -> float:
    return (metres - GEOMETRY.min_depth) / (GEOMETRY.max_depth - GEOMETRY.min_depth)


def test_recognition_label_nearest_goal_within_2_5_m() -> None:
    mask = torch.zeros(4, 8, 8, dtype=torch.uint8)
    depth = torch.ones(4, 8, 8, 1)
    # frame 0: category 2 at 2.0 m and category 5 at 1.0 m → 5 (stored 6)
    mask[0, 1:3, 1:3], depth[0, 1:3, 1:3] = 3, _normalised(2.0)
    mask[0, 5:7, 5:7], depth[0, 5:7, 5:7] = 6, _normalised(1.0)
    # frame 1: category 0 at 3 m and category 7 at 2.6 m → none
    mask[1, 1:3, 1:3], depth[1, 1:3, 1:3] = 1, _normalised(3.0)
    mask[1, 5:7, 5:7], depth[1, 5:7, 5:7] = 8, _normalised(2.6)
    # frame 2: a goal whose nearest pixel is at 2.4 m (the rest farther) → its category
    mask[2, 2:6, 2:6], depth[2, 2:6, 2:6] = 2, _normalised(4.0)
    depth[2, 3, 3] = _normalised(2.4)
    # frame 3: nothing, though the background is near
    depth[3] = 0.0
    assert recognition_label(mask, depth, GEOMETRY).tolist() == [6, 0, 2, 0]


def test_obj_recog_map_writes_prediction_at_agent_cell() -> None:
    _, space = _space("obj-recog-map")
    memory = ObjRecogMap(space, GEOMETRY)
    grid = memory.initial_state(3, torch.device("cpu"))["map"]
    gps = torch.tensor([[1.6, 0.8], [0.0, 0.0], [0.3, -0.3]])
    out = memory.write(grid, torch.tensor([4.0, 0.0, 8.0]), gps)
    assert out[0, C0 - 2, C0 - 1] == 4.0 and out[0].count_nonzero() == 1
    assert out[1].count_nonzero() == 0  # "no goal" is not written
    assert out[2, C0, C0] == 8.0 and out[2].count_nonzero() == 1
    # an overwrite keeps the newest prediction; positions off the map are dropped
    again = memory.write(
        out, torch.tensor([2.0, 3.0, 1.0]), torch.tensor([[1.6, 0.8], [100.0, 0.0], [0.0, 0.0]])
    )
    assert again[0, C0 - 2, C0 - 1] == 2.0 and again[1].count_nonzero() == 0


@pytest.mark.parametrize("position", [(0.0, 0.0), (2.4, -0.8)])
def test_egocentric_crop_is_rotated_to_the_heading(position: tuple[float, float]) -> None:
    gps = torch.tensor([position])
    row, col = C0 - round(position[0] / 0.8), C0 - round(position[1] / 0.8)
    crop, half = 25, 12
    for compass, ahead_cell, left_cell in (
        (0.0, (row - 2, col), (row, col - 2)),  # facing start-ahead: left is +y
        (math.pi / 2, (row, col - 2), (row + 2, col)),  # facing +y: ahead is +y, left is −x
        (-math.pi / 2, (row, col + 2), (row - 2, col)),
    ):
        grid = torch.zeros(1, 1, G, G)
        grid[0, 0, ahead_cell[0], ahead_cell[1]] = 1.0
        grid[0, 0, left_cell[0], left_cell[1]] = 2.0
        out = map_ops.egocentric_crop(grid, gps, torch.tensor([[compass]]), crop, CELL)[0, 0]
        assert out[half - 2, half] == 1.0, compass
        assert out[half, half - 2] == 2.0, compass
        assert out.count_nonzero() == 2


def test_dynamic_obj_recog_map_reads_only_the_current_goal() -> None:
    _, space = _space("dynamic-obj-recog-map")
    memory = ObjRecogMap(space, GEOMETRY, dynamic=True)
    seen = []
    memory.embedding.register_forward_hook(lambda module, args, out: seen.append(args[0].clone()))
    grid = torch.zeros(1, G, G)
    grid[0, C0 - 1, C0], grid[0, C0 + 1, C0] = 3.0, 5.0
    frame = {
        "gps": torch.zeros(1, 2),
        "compass": torch.zeros(1, 1),
        "goal": torch.tensor([4]),
        "recog_prediction": torch.zeros(1),
    }
    memory.step(frame, torch.zeros(1, 1), {"map": grid})
    assert sorted(seen[0].unique().tolist()) == [0, 5]


# ProjNeuralMap / EgoMap ------------------------------------------------------------------


def project(features, depth, valid):
    return map_ops.project_egocentric(features, depth, valid, GEOMETRY.hfov_deg, CELL)


def _single_feature(metres: float, column: int = 2, width: int = 5) -> tuple[torch.Tensor, ...]:
    features = torch.zeros(1, 2, 3, width)
    features[0, 0, 1, column] = 1.0
    depth = torch.full((1, 3, width), 1.0)
    depth[0, 1, column] = metres
    valid = torch.zeros(1, 3, width, dtype=torch.bool)
    valid[0, 1, column] = True
    return features, depth, valid


@pytest.mark.parametrize("metres", [0.3, 0.5, 1.0, 2.1, 3.9, 5.0, 5.1])
def test_projection_centre_column_lands_straight_ahead(metres: float) -> None:
    ego = project(*_single_feature(metres))
    assert ego.shape == (1, 2, map_ops.EGO_ROWS, map_ops.EGO_COLS)
    row = map_ops.EGO_ROWS - 1 - round(metres / 0.8)  # row k ahead: (k ± 0.5)·0.8 m
    assert ego[0, 0, row, map_ops.EGO_COLS // 2] == 1.0
    assert ego.count_nonzero() == 1


def test_projection_drops_far_and_invalid_points_and_maps_sides() -> None:
    for metres in (5.3, 5.7, 8.0):  # beyond the grid
        assert project(*_single_feature(metres)).count_nonzero() == 0
    features, depth, valid = _single_feature(2.0)
    assert project(features, depth, valid & False).count_nonzero() == 0
    # rightmost column at 4 m: bearing tan = 0.8·tan(39.5°) → 2.64 m to the right
    ego = project(*_single_feature(4.0, column=4))
    assert ego[0, 0, map_ops.EGO_ROWS - 1 - 5, map_ops.EGO_COLS // 2 + 3] == 1.0
    ego = project(*_single_feature(4.0, column=0))
    assert ego[0, 0, map_ops.EGO_ROWS - 1 - 5, map_ops.EGO_COLS // 2 - 3] == 1.0


def test_projection_combines_by_max_and_passes_gradients() -> None:
    features = torch.zeros(1, 1, 1, 3)
    features[0, 0, 0] = torch.tensor([0.2, 0.7, 0.4])
    features.requires_grad_(True)
    depth = torch.full((1, 1, 3), 3.0)  # all three in the cell 3 m ahead (±0.35 m sideways)
    ego = map_ops.project_egocentric(
        features, depth, torch.ones(1, 1, 3, dtype=torch.bool), 20.0, CELL
    )
    assert ego.count_nonzero() == 1 and ego.max().item() == pytest.approx(0.7)
    ego.sum().backward()
    assert features.grad[0, 0, 0].tolist() == [0.0, 1.0, 0.0]


def test_pool_depth_ignores_far_pixels() -> None:
    depth = torch.ones(1, 4, 4, 1)
    depth[0, :2, :2] = _normalised(2.0)
    depth[0, 2:, :2] = _normalised(1.0)
    depth[0, 3, :2] = 1.0  # half far: still valid, mean of the near half
    metres, valid = map_ops.pool_depth(depth, (2, 2), GEOMETRY)
    assert valid.tolist() == [[[True, False], [True, False]]]
    assert metres[0, 0, 0].item() == pytest.approx(2.0) and metres[0, 1, 0].item() == pytest.approx(
        1.0
    )


@pytest.mark.parametrize(
    ("gps", "compass", "cell"),
    [
        ((0.0, 0.0), 0.0, (C0 - 3, C0)),  # 2.4 m ahead of the start
        ((0.0, 0.0), math.pi / 2, (C0, C0 - 3)),  # turned left: 2.4 m along +y
        ((0.8, 0.0), -math.pi / 2, (C0 - 1, C0 + 3)),  # turned right from (0.8, 0): along −y
    ],
)
def test_registration_puts_features_in_the_world_cell(gps, compass, cell) -> None:
    ego = torch.zeros(1, 2, map_ops.EGO_ROWS, map_ops.EGO_COLS)
    ego[0, 1, map_ops.EGO_ROWS - 1 - 3, map_ops.EGO_COLS // 2] = 1.5  # centre 2.4 m ahead
    out = map_ops.register(
        torch.zeros(1, 2, G, G), ego, torch.tensor([gps]), torch.tensor([[compass]]), CELL
    )
    assert out[0, 1, cell[0], cell[1]] == 1.5
    assert out.count_nonzero() == 1


def test_registration_max_merge_and_gradients() -> None:
    ego = torch.zeros(1, 1, map_ops.EGO_ROWS, map_ops.EGO_COLS)
    ego[0, 0, map_ops.EGO_ROWS - 1, map_ops.EGO_COLS // 2] = 1.0  # the agent's own cell
    ego.requires_grad_(True)
    old = torch.zeros(1, 1, G, G)
    old[0, 0, C0, C0], old[0, 0, C0 + 5, C0] = 0.5, 3.0
    old.requires_grad_(True)
    out = map_ops.register(old, ego, torch.zeros(1, 2), torch.zeros(1, 1), CELL)
    assert out[0, 0, C0, C0] == 1.0 and out[0, 0, C0 + 5, C0] == 3.0
    out.sum().backward()
    assert ego.grad[0, 0, map_ops.EGO_ROWS - 1, map_ops.EGO_COLS // 2] == 1.0
    assert old.grad[0, 0, C0, C0] == 0.0 and old.grad[0, 0, C0 + 5, C0] == 1.0
    # a rotated grid leaves no holes, and every egocentric cell lands somewhere
    for compass in (math.pi / 6, -2 * math.pi / 3, 0.4):
        ego = torch.eye(91).view(1, 91, 7, 13)  # channel k marks egocentric cell k
        full = map_ops.register(
            torch.zeros(1, 91, G, G),
            ego,
            torch.tensor([[0.3, -0.5]]),
            torch.tensor([[compass]]),
            CELL,
        )[0]
        assert (full.flatten(1).amax(1) == 1.0).all()
        written = full.amax(0) > 0
        inner = written[1:-1, 1:-1]
        neighbours = written[:-2, 1:-1] & written[2:, 1:-1] & written[1:-1, :-2] & written[1:-1, 2:]
        assert not (neighbours & ~inner).any()
        assert 91 <= written.sum() <= 91 + 50


def _register_reference(global_map, ego, gps, compass):
    """Every sub-point of every egocentric cell, written one by one."""
    out = global_map.clone()
    for b in range(ego.shape[0]):
        yaw = float(compass[b, 0])
        for r in range(map_ops.EGO_ROWS):
            for q in range(map_ops.EGO_COLS):
                for da in (-0.2, 0.2):
                    for dl in (-0.2, 0.2):
                        ahead = (map_ops.EGO_ROWS - 1 - r) * 0.8 + da
                        left = (map_ops.EGO_COLS // 2 - q) * 0.8 + dl
                        x = float(gps[b, 0]) + ahead * math.cos(yaw) - left * math.sin(yaw)
                        y = float(gps[b, 1]) + ahead * math.sin(yaw) + left * math.cos(yaw)
                        row, col = math.floor(C0 + 0.5 - x / 0.8), math.floor(C0 + 0.5 - y / 0.8)
                        if 0 <= row < G and 0 <= col < G:
                            out[b, :, row, col] = torch.maximum(
                                out[b, :, row, col], ego[b, :, r, q]
                            )
    return out


def test_registration_matches_a_reference_near_the_edges() -> None:
    gen = torch.Generator().manual_seed(3)
    gps = torch.tensor([[0.1, -0.3], [24.0, 24.5], [-23.9, 20.0], [30.0, 0.0]])
    compass = torch.tensor([[0.3], [2.0], [-1.0], [math.pi]])
    ego = torch.rand(4, 3, map_ops.EGO_ROWS, map_ops.EGO_COLS, generator=gen)
    old = torch.rand(4, 3, G, G, generator=gen) * 0.8
    out = map_ops.register(old, ego, gps, compass, CELL)
    torch.testing.assert_close(out, _register_reference(old, ego, gps, compass))


def test_ego_map_attention_over_empty_map() -> None:
    _, space = _space("ego-map")
    memory = EgoMap(space, GEOMETRY, query_dim=12)
    grid = torch.zeros(2, 32, G, G, requires_grad=True)
    query = torch.randn(2, 12, requires_grad=True)
    read = memory.attend(grid, torch.zeros(2, 2), torch.zeros(2, 1), query)
    assert torch.equal(read, torch.zeros(2, memory.attention_dim))
    read.sum().backward()
    assert torch.isfinite(grid.grad).all() and torch.isfinite(query.grad).all()
    # one written cell: the read is its value, whatever the query
    grid = torch.zeros(1, 32, G, G)
    grid[0, :, 10, 20] = torch.rand(32) + 0.1
    read = memory.attend(grid, torch.zeros(1, 2), torch.zeros(1, 1), torch.randn(1, 12))
    blocks = map_ops.relative_cell_positions(torch.zeros(1, 2), torch.zeros(1, 1), G, CELL, pool=2)
    assert blocks.shape == (1, 32 * 32, 2)
    relative = blocks[0, 5 * 32 + 10]  # the 2 × 2 block of rows 10–11, columns 20–21
    torch.testing.assert_close(relative, torch.tensor([(C0 - 10.5) * 0.8, (C0 - 20.5) * 0.8]))
    expected = memory.key_value(grid[0, :, 10, 20]) + memory.position(
        memory.positional_features(relative)
    )
    torch.testing.assert_close(read[0], expected.chunk(2, -1)[1])


class _QuerySpy(Memory):
    """A memory that reads the GRU state and records the queries it is given."""

    reads_hidden = True
    out_dim = 4

    def __init__(self) -> None:
        super().__init__()
        self.queries: list[torch.Tensor] = []

    def step(self, frame, query, state):
        self.queries.append(query.detach().clone())
        return query[:, :4], state


def test_a_memory_that_reads_hidden_is_queried_with_the_previous_gru_state() -> None:
    _, space = _space("frmqn")
    spy = _QuerySpy()
    policy = RecurrentPolicy(space, spy)
    frames = _frames(space, steps=4, batch=2)
    starts = torch.zeros(4, 2)
    starts[2, 1] = 1.0  # env 1 starts a new episode at step 2
    initial = {"hidden": torch.randn(2, HIDDEN_SIZE)}
    with torch.no_grad():
        out = policy(frames, torch.ones(4, 2), starts, initial)
    queried = [q[:, -HIDDEN_SIZE:] for q in spy.queries]
    assert len(queried) == 4
    torch.testing.assert_close(queried[0], initial["hidden"])
    for t in (1, 2, 3):
        expected = _hidden_after(policy, frames, starts, initial, t)
        if t == 2:
            expected[1] = 0.0  # cleared by the episode start before the read
        torch.testing.assert_close(queried[t], expected)
    torch.testing.assert_close(
        out.state["hidden"], _hidden_after(policy, frames, starts, initial, 4)
    )


def _hidden_after(policy, frames, starts, initial, steps: int) -> torch.Tensor:
    """The GRU state after the first ``steps`` steps, from a fresh replay of just those steps."""
    with torch.no_grad():
        out = policy(
            {k: v[:steps] for k, v in frames.items()},
            torch.ones(steps, 2),
            starts[:steps],
            initial,
        )
    return out.state["hidden"].clone()


@pytest.mark.parametrize("name", ["obj-recog-map", "proj-neural-map", "ego-map", "oracle-map"])
def test_maps_take_every_parameter_from_the_env_config(name: str) -> None:
    """Field of view, depth range, cell size and crop size come from the env config (the one
    stored in a checkpoint), not from constants of the agents."""
    from multion_agents.learned.models import build_policy

    config = {
        "camera": {
            "width": SIZE,
            "height": SIZE,
            "hfov_deg": 90.0,
            "min_depth": 0.2,
            "max_depth": 4.0,
        },
        "maps": {"cell_size": 0.5, "ego_size": 13},
        "sensors": list(model_spec(name).train_sensors),
    }
    memory = build_policy(name, config).memory
    assert memory is not None
    if name != "oracle-map":
        assert memory.geometry == map_ops.MapGeometry(
            cell_size=0.5,
            crop_size=13,
            hfov_deg=90.0,
            min_depth=0.2,
            max_depth=4.0,
            normalized_depth=True,
        )
        assert memory.crop_size == 13
    first_conv = next(m for m in memory.cnn.net if isinstance(m, torch.nn.Conv2d))
    # the CNN is built for a 13-cell crop: 13 → 6 (stride 2) → 3×3 conv, 32 × 6 × 6 features
    assert memory.cnn.net[-2].in_features == 32 * 6 * 6 and first_conv.stride == (2, 2)
