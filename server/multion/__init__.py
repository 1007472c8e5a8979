"""MultiON on PyBullet: multi-object navigation benchmark (simulator, task, server)."""

from gymnasium.envs.registration import register

__version__ = "0.1.0"

# One Gymnasium id per task size; ``gym.make("MultiON/3-ON-v0")`` builds the val split by default.
for _m in (1, 2, 3):
    register(
        id=f"MultiON/{_m}-ON-v0",
        entry_point="multion.task.env:make_env",
        kwargs={"num_goals": _m},
    )

# The MultiON 2022 challenge's setting: 3-ON with 3 distractor cylinders (packaged val / test).
register(
    id="MultiON/3-ON-distractors-v0",
    entry_point="multion.task.env:make_env",
    kwargs={"num_goals": 3, "num_distractors": 3},
)
