"""``semMap`` (``maps.convention = "reference"``) against a literal transcription of the
reference code's construction (saimwani/multiON at 2ba4d25, ``habitat/core/env.py``).

The transcription builds the reference's ``currMap`` from this project's scene (occupancy only),
writes the goals with the reference's loop (l. 274-279), multiplies by the seen cells for the ego
map (l. 283-287), takes the heading from habitat's ``HeadingSensor`` applied to the agent's habitat
rotation, and cuts, rotates (``scipy.ndimage.rotate``, as the reference) and crops (l. 291-293).
Only the map's bounds differ: ``conv_grid`` here spans this house's map with 45 empty cells
around it, where the reference's spans ±120 m of Matterport3D.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from multion.config.datasets import load_dataset, packaged_dataset_path
from multion.config.episode import Episode
from multion.config.ranges import ConfigError
from multion.config.task import EnvConfig, MapConfig, TaskConfig
from multion.task.env import MultiONEnv
from multion.task.maps import OracleMap
from multion.task.multion_import import rotation_from_yaw, world_to_habitat
from multion_client.constants import REFERENCE_CATEGORY_NAMES, REFERENCE_TO_CATEGORY
from multion_client.semantic_map import reference_sem_map

CATEGORY_TO_REFERENCE = tuple(REFERENCE_TO_CATEGORY.index(c) for c in range(8))
"""The reference's index of each category id here (habitat_compat's colour order)."""
MARGIN = 45  # empty cells around the house: more than the 40 of the reference's patch


class ReferenceTranscription:
    """``habitat/core/env.py``'s oracle map for one episode, on this project's map."""

    def __init__(self, oracle: OracleMap, episode: Episode, trainer_name: str) -> None:
        self.cell = oracle.coarse_size
        rows, cols = oracle.layers.shape[:2]
        origin_x, origin_y = oracle.origin
        # habitat x = our x, habitat z = our -y (multion.task.multion_import)
        self.x_max = origin_x + (cols + MARGIN) * self.cell
        self.z_min = -(origin_y + (rows + MARGIN) * self.cell)
        self.size = max(rows, cols) + 2 * MARGIN
        # mapCache: occupancy; "oracle-ego" adds 1 to every channel (l. 137-139)
        occupancy = oracle.layers[..., 0].astype(np.int64)
        cache = np.zeros((self.size, self.size, 2), dtype=np.int64)
        row_index, col_index = np.nonzero(np.ones((rows, cols), dtype=bool))
        self.cell_rows, self.cell_cols = row_index, col_index
        centres_x = origin_x + (col_index + 0.5) * self.cell
        centres_y = origin_y + (row_index + 0.5) * self.cell
        self.grid_x, self.grid_y = self.conv_grid(centres_x, -centres_y)
        cache[self.grid_x, self.grid_y, 0] = occupancy[row_index, col_index]
        if trainer_name == "oracle-ego":
            cache += 1
        self.trainer_name = trainer_name
        # reset: goals as grid_loc ± 1, category (the reference's order) + objIndexOffset (l. 279)
        self.curr_map = np.copy(cache)
        offset = 1 if trainer_name == "oracle" else 2
        for goal in (*episode.goals, *episode.distractors):
            loc0, _, loc2 = world_to_habitat(goal.position)
            grid_loc = self.conv_grid(loc0, loc2)
            reference_id = REFERENCE_TO_CATEGORY.index(goal.category)
            self.curr_map[
                grid_loc[0] - 1 : grid_loc[0] + 2, grid_loc[1] - 1 : grid_loc[1] + 2, 1
            ] = reference_id + offset

    def conv_grid(
        self, realworld_x: float | np.ndarray, realworld_y: float | np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """l. 214-233, with this map's bounds (``int()`` truncates as ``astype`` does)."""
        grid_x = np.asarray((self.x_max - realworld_x) / self.cell).astype(np.int64)
        grid_y = np.asarray((realworld_y - self.z_min) / self.cell).astype(np.int64)
        return grid_x, grid_y

    def sem_map(self, position: np.ndarray, yaw: float, seen: np.ndarray | None) -> np.ndarray:
        agent_x, _, agent_z = world_to_habitat((position[0], position[1], 0.0))
        curr_pix = self.conv_grid(agent_x, agent_z)
        if self.trainer_name == "oracle-ego":
            assert seen is not None
            expose = np.zeros((self.size, self.size, 2), dtype=np.int64)
            expose[self.grid_x, self.grid_y] = seen[self.cell_rows, self.cell_cols, None]
            patch = self.curr_map * expose
        else:
            patch = self.curr_map
        heading = heading_sensor(rotation_from_yaw(yaw))
        patch = patch[curr_pix[0] - 40 : curr_pix[0] + 40, curr_pix[1] - 40 : curr_pix[1] + 40, :]
        patch = ndimage.rotate(patch, -(heading * 180 / np.pi) + 90, order=0, reshape=False)
        return patch[40 - 25 : 40 + 25, 40 - 25 : 40 + 25, :]


def heading_sensor(rotation: list[float]) -> float:
    """habitat's ``HeadingSensor`` (``habitat/tasks/nav/nav.py``): the agent's -z axis turned by
    the inverse rotation, ``phi = atan2(v[0], -v[2])``."""
    x, y, z, w = rotation
    inverse = np.array([w, -x, -y, -z])  # (w, x, y, z)
    vector = np.array([0.0, 0.0, -1.0])
    qw, qv = inverse[0], inverse[1:]
    turned = vector + 2 * qw * np.cross(qv, vector) + 2 * np.cross(qv, np.cross(qv, vector))
    return math.atan2(turned[0], -turned[2])


def episodes_in_houses(count: int) -> list[Episode]:
    """The first episode of ``count`` different houses of the packaged 3-ON val set."""
    chosen: dict[str, Episode] = {}
    for episode in load_dataset(packaged_dataset_path(3, "val")):
        chosen.setdefault(episode.scene_id, episode)
        if len(chosen) == count:
            break
    return list(chosen.values())


def agreement(
    sensor: str, convention: str, houses: int = 3, steps: int = 60
) -> tuple[float, float]:
    """Fractions of semMap cells equal to the transcription's, of all cells and of the cells
    either map marks (most of a 40 m crop is empty beyond the house), over ``steps`` random
    actions (turns and moves: many poses and headings) in each of ``houses`` houses."""
    trainer = "oracle" if sensor == "oracle_map" else "oracle-ego"
    rng = np.random.default_rng(7)
    equal = total = marked_equal = marked = 0
    for episode in episodes_in_houses(houses):
        config = EnvConfig(
            task=TaskConfig(num_goals=episode.num_goals, max_steps=1000),
            maps=MapConfig(convention=convention),
            sensors=(sensor,),
        )
        env = MultiONEnv(config, episodes=[episode])
        obs, _ = env.reset(seed=0)
        assert env._oracle is not None and env._reveal is not None
        reference = ReferenceTranscription(env._oracle, episode, trainer)
        for _ in range(steps):
            seen = env._reveal.seen if sensor == "oracle_ego_map" else None
            expected = reference.sem_map(env.sim.position, env.sim.yaw, seen)
            got = reference_sem_map(obs[sensor], sensor, CATEGORY_TO_REFERENCE)
            same = got == expected
            informative = (got != 0) | (expected != 0)
            equal, total = equal + int(same.sum()), total + same.size
            marked_equal += int((same & informative).sum())
            marked += int(informative.sum())
            # never FOUND (0): turn or move, mostly forward, to see many cells and headings
            obs, *_ = env.step(int(rng.choice([1, 1, 2, 3])))
        env.close()
    return equal / total, marked_equal / marked


@pytest.mark.parametrize("sensor", ["oracle_map", "oracle_ego_map"])
def test_sem_map_is_the_reference_map_cell_for_cell(sensor: str) -> None:
    cells, marked_cells = agreement(sensor, "reference")
    assert cells >= 0.99 and marked_cells >= 0.99, (
        f"{sensor}: {cells:.2%} of semMap cells, {marked_cells:.2%} of marked ones, equal "
        "the reference's"
    )


def test_the_project_crop_is_not_the_reference_map() -> None:
    """The comparison can fail: the project's own crop (ahead up) is far from the reference's."""
    cells, marked_cells = agreement("oracle_map", "project", houses=1, steps=20)
    assert marked_cells < 0.5, f"{cells:.2%} of cells, {marked_cells:.2%} of marked ones"


def test_reference_crop_has_ahead_down_and_left_to_the_right() -> None:
    """A 3 × 3 square 4 m ahead lies 5 rows below the agent; one 4 m to the left, 5 columns to
    its right; the agent's own cell lands in (24|25, 24|25), the 4 cells around the centre point
    (nearest-cell sampling can double or drop it at some headings, as the reference's does)."""
    episode = episodes_in_houses(1)[0]
    config = EnvConfig(
        task=TaskConfig(num_goals=episode.num_goals),
        maps=MapConfig(convention="reference"),
        sensors=("oracle_map",),
    )
    env = MultiONEnv(config, episodes=[episode])
    env.reset(seed=0)
    oracle = env._oracle
    assert oracle is not None
    position = env.sim.position
    agent_seen = 0
    for degrees in range(0, 360, 15):
        yaw = math.radians(degrees)
        ahead = position + 4.0 * np.array([math.cos(yaw), math.sin(yaw)])
        left = position + 4.0 * np.array([-math.sin(yaw), math.cos(yaw)])
        layers = np.zeros_like(oracle.layers)
        layers[(*oracle.coarse_cell(position), 0)] = 1
        for value, point in ((2, ahead), (3, left)):
            row, col = oracle.coarse_cell(point)
            layers[row - 1 : row + 2, col - 1 : col + 2, 1] = value
        crop = oracle.egocentric(layers, position, yaw)
        agent_cells = np.argwhere(crop[..., 0] == 1)
        assert set(agent_cells.ravel().tolist()) <= {24, 25}, (degrees, agent_cells)
        agent_seen += len(agent_cells) > 0
        ahead_centre = np.argwhere(crop[..., 1] == 2).mean(axis=0) - 24.5
        left_centre = np.argwhere(crop[..., 1] == 3).mean(axis=0) - 24.5
        assert abs(ahead_centre[0] - 5) <= 1.5 and abs(ahead_centre[1]) <= 1.5, degrees
        assert abs(left_centre[0]) <= 1.5 and abs(left_centre[1] - 5) <= 1.5, degrees
    assert agent_seen >= 20
    env.close()


def test_a_bad_convention_is_refused_naming_the_choices() -> None:
    with pytest.raises(ConfigError, match=r"maps.convention = 'habitat' is not allowed.*reference"):
        MapConfig(convention="habitat")


def test_reference_sem_map_renumbers_objects_and_keeps_the_seen_mark() -> None:
    crop = np.zeros((2, 2, 2), dtype=np.uint8)
    crop[0, 0] = (2, 1)  # seen, no object
    crop[1, 1] = (2, REFERENCE_TO_CATEGORY[REFERENCE_CATEGORY_NAMES.index("cyan")] + 2)
    ego = reference_sem_map(crop, "oracle_ego_map", CATEGORY_TO_REFERENCE)
    assert ego[0, 0].tolist() == [2, 1] and ego[0, 1].tolist() == [0, 0]
    assert ego[1, 1, 1] == REFERENCE_CATEGORY_NAMES.index("cyan") + 2
    crop[1, 1, 1] = 11
    with pytest.raises(ValueError, match="oracle_ego_map holds object value 11.*0..9"):
        reference_sem_map(crop, "oracle_ego_map", CATEGORY_TO_REFERENCE)
    with pytest.raises(ValueError, match="sensor must be one of"):
        reference_sem_map(crop, "semMap", CATEGORY_TO_REFERENCE)
