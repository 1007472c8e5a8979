"""The leaderboard: hidden challenge episodes, teams and tokens, submission runs, results.

Built on ``multion.api`` (the session registry and its simulator workers) and ``multion.task``;
neither imports it, except ``create_app`` / ``multion serve`` which turn it on with a challenge
file and a database. See ``docs/leaderboard.md``.
"""
