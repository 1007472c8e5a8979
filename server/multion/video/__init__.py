"""Episode videos, shared by ``multion video`` (agents) and the leaderboard's run pages.

An episode is played again from its stored actions in this process with an RGB-D camera
(:mod:`.replay`), each step drawn beside a top-down map (:mod:`.frames`), encoded to H.264 MP4
(:mod:`.encoder`, PyAV: the optional ``[video]`` extra) with a WebVTT caption track
(:mod:`.captions`); :mod:`.film` puts them together. :mod:`.stored` holds what a film is made of,
its length cap and its errors, with no simulator: the leaderboard's server process checks and
queues films with it, and a helper process makes them.
"""
