"""``multion bench``: speed measured in one run, printed as ratios (:mod:`.cli` says which).

Benchmarks are tools for the developers, not part of the benchmark itself; they gather here, in
the top package, so that they may use every layer below (the simulator, the server, the
leaderboard, the agents and the trainer) without those layers knowing about them.
"""
