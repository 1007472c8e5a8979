"""Helpers every layer of the server may use, below the configs: bootstrap statistics
(:mod:`.stats`) and process limits and signals (:mod:`.processes`). They import nothing of
``multion``, nor the simulator, torch or a web framework."""
