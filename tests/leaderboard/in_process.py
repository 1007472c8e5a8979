"""A leaderboard server in a thread of the test process, so that its runs follow the test's
:class:`~multion.leaderboard.clock.ManualClock`: an expiry test advances the clock instead of
sleeping until a step budget has passed. Over real HTTP, with real simulator workers, the
settings of ``conftest.start_server``."""

from __future__ import annotations

import threading
from pathlib import Path
from types import TracebackType

import uvicorn
from server_settings import LEADERBOARD, MAX_REQUEST_BYTES

from multion.api.app import create_app
from multion.api.local_server import free_port
from multion.api.settings import ServerSettings
from multion.leaderboard.app import LeaderboardExtension
from multion.leaderboard.clock import ManualClock
from multion.leaderboard.settings import LeaderboardSettings
from waiting import wait_until


class InProcessServer:
    """``with InProcessServer(challenge_file, database, clock) as server: ... server.url``."""

    def __init__(
        self, challenge_file: Path, database: str, clock: ManualClock, workers: int = 1
    ) -> None:
        self.clock = clock
        port = free_port()
        self.url = f"http://127.0.0.1:{port}"
        settings = ServerSettings(port=port, workers=workers, max_request_bytes=MAX_REQUEST_BYTES)
        leaderboard = LeaderboardSettings(
            challenge=challenge_file, database=database, **LEADERBOARD
        )
        app = create_app(settings, [LeaderboardExtension(leaderboard, clock)])
        # log_config=None: uvicorn leaves the test process's logging as pytest set it
        config = uvicorn.Config(app, host="127.0.0.1", port=port, log_config=None,
                                access_log=False, timeout_graceful_shutdown=10)  # fmt: skip
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, name="leaderboard", daemon=True)

    def start(self) -> InProcessServer:
        self.thread.start()
        wait_until(lambda: self.server.started or not self.thread.is_alive(), timeout=120,
                   message="the in-process server to start")  # fmt: skip
        if not self.server.started:
            raise RuntimeError("the in-process server failed to start (its log says why)")
        return self

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(60)

    def __enter__(self) -> InProcessServer:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
