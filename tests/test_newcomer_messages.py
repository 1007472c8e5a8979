"""What a newcomer sees: no PyBullet or EGL chatter, and errors that say what to do (install
torch with ``setup.sh --dev``, generate a train dataset), as commands run in a fresh process."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from multion.config.codec import env_config_from_dict
from multion_agents.config_overrides import parse_env_overrides
from multion_agents.registry import LEARNED_AGENT_NAMES

# `multion ARGS` with torch's import blocked, as on a machine set up without --dev
WITHOUT_TORCH = (
    "import sys; sys.modules['torch'] = None; from multion_agents.cli import main; "
    "sys.exit(main(sys.argv[1:]))"
)


def multion(*args: str, torch: bool = True) -> subprocess.CompletedProcess[str]:
    command = ["-m", "multion_agents.cli"] if torch else ["-c", WITHOUT_TORCH]
    return subprocess.run(
        [sys.executable, *command, *args], capture_output=True, text=True, timeout=300
    )


def test_no_pybullet_banner_on_a_command() -> None:
    result = multion("dataset", "--help")
    assert result.returncode == 0
    assert "pybullet build time" not in result.stdout + result.stderr


EGL_SCRIPT = """
from multion.config.codec import env_config_from_dict
from multion.sim.camera import resolve_renderer
from multion.task.env import MultiONEnv

renderer = resolve_renderer("auto")
config = {"camera": {"width": 16, "height": 16, "renderer": renderer}, "task": {"num_goals": 1}}
env = MultiONEnv(env_config_from_dict(config))
env.reset(seed=0)
env.step(2)
env.close()
print("renderer", renderer)
"""


def test_no_egl_device_lines_when_the_renderer_is_probed_and_renders() -> None:
    # "auto" loads the EGL plugin where Mesa's EGL is installed (it prints its device, vendor
    # and version when loaded, "ven = …" when it renders new bodies, and a goodbye on
    # disconnect), else falls back to tiny (then this checks the tiny path only).
    result = subprocess.run(
        [sys.executable, "-c", EGL_SCRIPT], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    assert re.fullmatch(r"renderer (tiny|gl|egl)\n", result.stdout), result.stdout
    assert result.stderr == ""


def test_a_learned_agent_without_torch_names_setup_dev() -> None:
    result = multion("eval", "--agent", "oracle-map", "--episodes", "1", torch=False)
    assert result.returncode != 0
    assert "'oracle-map' is a learned agent" in result.stderr, result.stderr
    assert "--checkpoint" in result.stderr and "setup.sh --dev" in result.stderr
    with_checkpoint = multion(
        "eval", "--agent", "oracle-map", "--checkpoint", "om.pt", "--episodes", "1", torch=False
    )
    assert with_checkpoint.returncode != 0 and "Traceback" not in with_checkpoint.stderr
    assert "setup.sh --dev" in with_checkpoint.stderr, with_checkpoint.stderr


@pytest.mark.parametrize("option", ["--list", "--help"])
def test_train_without_torch_names_setup_dev(option: str) -> None:
    result = multion("train", option, torch=False)
    assert "multion train` is unavailable" in result.stdout + result.stderr
    assert "setup.sh --dev" in result.stdout + result.stderr


def test_unknown_options_are_still_refused() -> None:
    result = multion("dataset", "check", "x.json.gz", "--bogus")
    assert result.returncode == 2 and "unrecognized arguments: --bogus" in result.stderr


def test_the_train_split_without_a_dataset_says_how_to_make_one() -> None:
    result = multion("eval", "--agent", "random", "--split", "train", "--episodes", "1")
    assert result.returncode != 0
    assert "multion dataset generate --task 3-on --split train" in result.stderr, result.stderr
    assert "--dataset FILE" in result.stderr


def test_the_examples_of_eval_help_are_real_fields() -> None:
    text = " ".join(multion("eval", "--help").stdout.split())
    examples = re.findall(r"--set ([a-z_]+\.[a-z_]+=\S+)", text)
    assert len(examples) >= 3, text
    for example in examples:
        env_config_from_dict(parse_env_overrides([example]))  # a ConfigError names a bad field


def test_the_learned_agent_names_are_those_of_the_models() -> None:
    pytest.importorskip("torch")
    from multion_agents.learned.models import MODELS

    assert LEARNED_AGENT_NAMES == tuple(MODELS)
