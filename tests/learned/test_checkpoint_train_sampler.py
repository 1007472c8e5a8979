"""A checkpoint written before issue 44 trained on online episodes: its recorded config, which
has no ``task.train_sampler``, reads as ``online`` (so a resume that would switch it to goal
sites is refused), while a config that names its sampler keeps it."""

from __future__ import annotations

from multion.config.codec import env_config_from_dict, env_config_to_dict
from multion.config.task import EnvConfig, TaskConfig
from multion_agents.learned.checkpoint import with_legacy_fields


def test_a_config_recorded_before_issue_44_reads_as_the_online_sampler() -> None:
    recorded = env_config_to_dict(EnvConfig(split="train"))
    del recorded["task"]["train_sampler"]
    assert env_config_from_dict(recorded).task.train_sampler == "sites"  # today's default
    old = env_config_from_dict(with_legacy_fields(recorded))
    assert old.task.train_sampler == "online"
    assert old != env_config_from_dict(recorded)  # the resume check sees the difference


def test_a_config_that_names_its_sampler_keeps_it() -> None:
    recorded = env_config_to_dict(EnvConfig(split="train", task=TaskConfig(train_sampler="sites")))
    assert env_config_from_dict(with_legacy_fields(recorded)).task.train_sampler == "sites"
