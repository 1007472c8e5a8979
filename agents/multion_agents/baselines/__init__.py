"""Non-learned baselines: the paper's random agents and two planners that need no training."""
