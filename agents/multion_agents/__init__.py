"""MultiON agents: baselines, learned agents, their training and evaluation, the benches."""

import os

# torch's OpenMP threads (the PPO update runs on every core) otherwise spin while they wait;
# where simulator processes or other jobs share the cores, the spinning threads take turns with
# them and an update ran 10x slower (issue 44: 2 cores under a load of 8, update 89.8 ->
# 10.2 ms/frame). Read when torch loads, so it must be set before the first `import torch`.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
