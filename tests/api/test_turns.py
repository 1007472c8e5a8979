"""A simulator worker's turns (issue 53 item 7): steps go before the resets and creations
waiting with them, and a slower request is passed at most MAX_OVERTAKES times."""

from __future__ import annotations

import asyncio

import pytest

from multion.api.turns import MAX_OVERTAKES, TurnQueue


async def _served(arrivals: list[tuple[str, bool]]) -> list[str]:
    """The order in which requests (name, urgent), all queued behind one holding the worker,
    are served."""
    turns, order = TurnQueue(), []
    await turns.acquire(urgent=False)  # a reset in progress

    async def request(name: str, urgent: bool) -> None:
        async with turns.turn(urgent):
            order.append(name)
            await asyncio.sleep(0)

    tasks = []
    for name, urgent in arrivals:
        tasks.append(asyncio.create_task(request(name, urgent)))
        await asyncio.sleep(0)  # queued in this order
    assert turns.waiting == len(arrivals)
    turns.release()
    await asyncio.gather(*tasks)
    return order


def test_a_step_goes_before_the_resets_queued_ahead_of_it() -> None:
    arrivals = [("reset a", False), ("reset b", False), ("step c", True), ("create d", False)]
    order = asyncio.run(_served(arrivals))
    assert order == ["step c", "reset a", "reset b", "create d"]  # was: arrival order


def test_a_reset_is_passed_by_a_bounded_number_of_steps() -> None:
    steps = [(f"step {k}", True) for k in range(MAX_OVERTAKES + 5)]
    order = asyncio.run(_served([("reset", False), *steps]))
    assert order.index("reset") == MAX_OVERTAKES


def test_a_cancelled_waiter_leaves_the_queue_and_the_turn_passes_on() -> None:
    async def scenario() -> list[str]:
        turns, order = TurnQueue(), []
        await turns.acquire(urgent=False)

        async def request(name: str, urgent: bool) -> None:
            async with turns.turn(urgent):
                order.append(name)

        gone = asyncio.create_task(request("gone", True))
        kept = asyncio.create_task(request("kept", False))
        await asyncio.sleep(0)
        gone.cancel()
        with pytest.raises(asyncio.CancelledError):
            await gone
        turns.release()
        await kept
        assert turns.waiting == 0
        await asyncio.wait_for(turns.acquire(urgent=True), 1)  # free again
        return order

    assert asyncio.run(scenario()) == ["kept"]
