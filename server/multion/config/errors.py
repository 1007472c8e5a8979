"""The root of every error that is the user's mistake, not a bug: :class:`UsageError`.

A bad config value, an unknown scene id, a missing checkpoint, a challenge file that does not
parse: each package roots its errors here, so the command-line tools catch ``UsageError`` alone
(one-line message, exit status 2) and let anything else, a bug, print its traceback. The errors a
client can cause through the API also derive from the matching wire error of
:mod:`multion_client.errors` (``InvalidConfig``, ``InvalidEpisode``, ...), whose ``code`` and
``status`` the server answers with.

This module sits in the lowest configuration layer and imports nothing heavy, so every package
can use it.
"""

from __future__ import annotations


class UsageError(Exception):
    """Input that cannot be used; the message says what and why, in one line fit to show as is.

    ``str()`` is the bare message, also where a subclass is a wire error (whose own ``str()``
    prefixes the code): the command-line tools and the server's messages print it unchanged."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""
