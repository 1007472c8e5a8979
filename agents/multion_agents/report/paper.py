"""The paper's numbers (Table 3, the supplement's seen / not-seen, found-budget and colour vs
shape tables).

They live in one data file, ``multion_agents/data/paper_results.json``, with their source; this
module only reads it. The paper evaluated on the Matterport3D *test* set, in other buildings and
another simulator, so its numbers are shown beside ours for scale, never merged with them.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources
from typing import Any


@dataclass(frozen=True)
class PaperResults:
    source: str
    setting: str
    agents: dict[str, str]
    """Our agent name → the paper's row name (e.g. ``random-oracle-found`` → ``Rand+OracleFound``)."""
    table3: dict[str, Any]
    seen_not_seen: dict[str, Any]
    found_budget: dict[str, Any]
    colour_vs_shape: dict[str, Any]

    def counterpart(self, agent: str) -> str | None:
        """The paper's row for our ``agent``, or None when the paper has no such agent."""
        return self.agents.get(agent)

    def table3_row(self, agent: str, num_goals: int) -> dict[str, float] | None:
        """The paper's Success, Progress, SPL, PPL (percent) of ``agent`` on m-ON, if any."""
        row = self.table3["rows"].get(self.counterpart(agent) or "")
        if row is None or not 1 <= num_goals <= len(row["success"]):
            return None
        return {metric: float(values[num_goals - 1]) for metric, values in row.items()}

    def seen_row(self, agent: str, num_goals: int, goal: int) -> dict[str, float] | None:
        """The paper's seen / not-seen success (percent) of goal k on its task, if any."""
        if f"{num_goals}-on" != self.seen_not_seen["task"]:
            return None
        row = self.seen_not_seen["rows"].get(self.counterpart(agent) or "", {})
        found: dict[str, float] | None = row.get(str(goal))
        return found

    def budget_row(self, agent: str, num_goals: int, budget: int) -> dict[str, float] | None:
        """The paper's found-budget row (percent) for ``agent`` on its task, if any."""
        table = self.found_budget
        if self.counterpart(agent) != table["agent"] or f"{num_goals}-on" != table["task"]:
            return None
        found: dict[str, float] | None = table["rows"].get(str(budget))
        return found

    def goal_set_row(self, agent: str, num_goals: int, goal_set: str) -> dict[str, float] | None:
        """The paper's Success, Progress, SPL, PPL (percent) of ``agent`` on m-ON with the goal
        set ``goal_set`` (``colours`` or ``shapes``), if the supplement has it."""
        table = self.colour_vs_shape
        row = table["rows"].get(goal_set)
        if self.counterpart(agent) != table["agent"] or row is None:
            return None
        if not 1 <= num_goals <= len(row["success"]):
            return None
        return {metric: float(values[num_goals - 1]) for metric, values in row.items()}


@functools.cache
def paper_results() -> PaperResults:
    text = resources.files("multion_agents").joinpath("data/paper_results.json").read_text("utf-8")
    data = json.loads(text)
    return PaperResults(
        source=data["source"],
        setting=data["setting"],
        agents=data["agents"],
        table3=data["table3"],
        seen_not_seen=data["seen_not_seen"],
        found_budget=data["found_budget"],
        colour_vs_shape=data["colour_vs_shape"],
    )
