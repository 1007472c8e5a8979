"""Evaluation plays episodes grouped by scene, so each environment builds each house once."""

from __future__ import annotations

from dataclasses import replace

from multion_agents.evaluate import scene_order


def test_episodes_are_grouped_by_scene_in_order_of_first_appearance(room_episodes) -> None:
    base = room_episodes(6, 0, "order")
    scenes = ["house-b", "house-a", "house-b", "house-c", "house-a", "house-b"]
    episodes = [replace(e, scene_id=s) for e, s in zip(base, scenes, strict=True)]
    assert scene_order(episodes) == [0, 2, 5, 1, 4, 3]
    assert scene_order(episodes[:1]) == [0] and scene_order([]) == []
