"""The leaderboard's web pages: queries, charts, episode pictures, routes and templates."""
