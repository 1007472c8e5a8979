"""The light paths stay light: the config package and ``multion --help`` load neither PyBullet
nor torch (nor FastAPI for the configs), so agents and tools can read configs cheaply."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("pybullet", "torch")


def loaded_after(code: str) -> set[str]:
    """The top-level modules loaded in a fresh interpreter after running ``code``."""
    probe = f"{code}\nimport sys\nprint(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    return set(result.stdout.split("\n")[-2].split())


def test_the_config_package_loads_no_simulator_torch_or_web_framework() -> None:
    loaded = loaded_after(
        "import multion.config, multion.config.codec, multion.config.episode, "
        "multion.config.ranges, multion.config.scenes, multion.config.sim, multion.config.task\n"
        "multion.config.codec.env_config_from_dict({'camera': {'width': 64}})"
    )
    assert not {*HEAVY, "fastapi", "scipy"} & loaded


def test_multion_help_loads_no_simulator_or_torch() -> None:
    loaded = loaded_after(
        "import contextlib, io\n"
        "from multion_agents.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert main([]) == 2"
    )
    assert "multion_agents" in loaded
    assert not set(HEAVY) & loaded


def test_reading_a_dataset_builds_no_scene_and_loads_no_simulator() -> None:
    loaded = loaded_after(
        "from multion.config.datasets import load_dataset, packaged_dataset_path, parse_task\n"
        "assert load_dataset(packaged_dataset_path(parse_task('1-on'), 'val'))"
    )
    assert "multion" in loaded
    assert not {*HEAVY, "scipy", "skfmm"} & loaded
    modules = loaded_modules_after("import multion.config.datasets")
    assert not [m for m in modules if m.startswith(("multion.scenes", "multion.sim"))]


def test_eval_and_train_settings_and_the_report_load_no_simulator() -> None:
    loaded = loaded_after(
        "import multion_agents.eval_settings, multion_agents.learned.train_settings\n"
        "import multion_agents.report.tables, multion_agents.report.runs\n"
        "import multion_agents.report.variants, multion_agents.report.run_summary"
    )
    assert "multion_agents" in loaded
    assert "pybullet" not in loaded


def loaded_modules_after(code: str) -> list[str]:
    """Every module (dotted) loaded in a fresh interpreter after running ``code``."""
    probe = f"{code}\nimport sys\nprint(' '.join(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    return result.stdout.split("\n")[-2].split()
