"""The paper's learned agents (§4): models (``models.MODELS``), PPO / DD-PPO training
(``ppo``), checkpoints, and :class:`~multion_agents.learned.agent.LearnedAgent` for ``multion eval``.

Needs the ``train`` extra (torch); nothing else in ``multion_agents`` imports this package.
"""
