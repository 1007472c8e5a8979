"""``multion serve``'s options are generated from the settings classes: each setting declared
once, its default and environment variable named in the help (issue 45 item 5)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from multion.api import cli_serve
from multion.api.settings import ServerSettings
from multion.leaderboard import cli_serve as leaderboard_serve
from multion.leaderboard.settings import LeaderboardSettings


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    leaderboard_serve.add_arguments(parser)
    return parser


def _flag(name: str) -> str:
    return f"--{name.replace('_', '-')}"


@pytest.mark.parametrize("settings", [ServerSettings, LeaderboardSettings])
def test_every_setting_has_an_option_naming_its_default_and_variable(
    settings: type[ServerSettings] | type[LeaderboardSettings],
) -> None:
    help_text = " ".join(_parser().format_help().split())
    prefix = settings.model_config["env_prefix"]
    for name, field in settings.model_fields.items():
        if name == cli_serve.DATASET_DIRS:
            assert "--dataset-dir DIR" in help_text
            continue
        assert _flag(name) in help_text, name
        assert f"env {prefix}{name.upper()}" in help_text, name
        if not field.is_required():
            default = field.get_default(call_default_factory=True)
            shown = "none" if default is None else default
            assert f"(default {shown}; env {prefix}{name.upper()})" in help_text, name


def test_options_given_become_settings_and_the_others_keep_their_defaults() -> None:
    args = _parser().parse_args(
        ["--workers", "3", "--sessions", "token", "--replica", "r1", "--dataset-dir", "/d"]
    )
    settings = cli_serve.settings_from_args(args)
    assert (settings.workers, settings.sessions, settings.replica) == (3, "token", "r1")
    assert settings.allowed_dataset_dirs == [Path("/d")]
    assert settings.max_sessions == ServerSettings.model_fields["max_sessions"].default
    assert settings.worker_start_timeout_s == 120.0


def test_literal_settings_offer_their_values_and_refuse_others(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit):
        _parser().parse_args(["--live-view", "public"])
    assert "invalid choice: 'public' (choose from" in capsys.readouterr().err


def test_leaderboard_switches_are_generated_too() -> None:
    args = _parser().parse_args(["--no-warm-up", "--token-cache-s", "2.5"])
    assert (args.warm_up, args.token_cache_s, args.draw_pictures) == (False, 2.5, None)


def test_a_setting_type_without_a_command_line_form_is_refused_when_declared() -> None:
    with pytest.raises(TypeError, match="no command-line form"):
        cli_serve._option_type(dict[str, int])
