"""The scripts in scripts/ run (they import from the packages, and moves there broke them once)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from multion_agents.report.document import BEGIN, END

ROOT = Path(__file__).resolve().parents[1]
PYTHON_SCRIPTS = sorted((ROOT / "scripts").glob("*.py"))


def run(*args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.parametrize("script", PYTHON_SCRIPTS, ids=lambda p: p.name)
def test_every_script_answers_help(script: Path) -> None:
    done = run(str(script), "--help", timeout=120)
    assert done.returncode == 0, done.stderr
    assert "usage:" in done.stdout


def test_the_calibration_plays_and_reads_its_runs(tmp_path: Path) -> None:
    played = run("scripts/calibrate_houses.py", "--tasks", "1", "--episodes", "2",
                 "--out", str(tmp_path))  # fmt: skip
    assert played.returncode in (0, 1), played.stderr  # 1: outside the band (2 episodes)
    assert (tmp_path / "random-oracle-found-1on" / "metrics.json").is_file()
    table = run("scripts/calibrate_houses.py", "--tasks", "1", "--from-runs", str(tmp_path))
    assert table.returncode in (0, 1), table.stderr
    row = next(line for line in table.stdout.splitlines() if line.lstrip().startswith("1"))
    assert "26" in row  # the paper's Rand+OracleFound 1-ON figure beside ours


@pytest.mark.slow
def test_central_comparison_runs_resumes_and_publishes(tmp_path: Path) -> None:
    """scripts/central_comparison.sh at a toy budget (one update per agent, 2 val episodes), in
    a copy of the repository's layout: it trains and evaluates the core agents, a second run
    skips what is done, PUBLISH=1 keeps the runs and regenerates the doc's tables, and a run
    into an empty OUT (a fresh clone) restores the published runs instead of training again."""
    _copy_script(tmp_path, "central_comparison.sh")
    doc = tmp_path / "docs" / "learned.md"
    doc.parent.mkdir()
    doc.write_text(f"# Learned\n\n{BEGIN}\n{END}\n")
    env = {
        **os.environ,
        "OUT": "runs/central",
        "FRAMES": "1024",
        "EPISODES": "2",
        "STAGES": "core",
        "MULTION": f"{sys.executable} -m multion_agents.cli",
    }
    script = ["bash", "scripts/central_comparison.sh"]
    first = subprocess.run(script, cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=1200)  # fmt: skip
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    out = tmp_path / "runs" / "central"
    for name in ("oracle-map", "no-map", "oracle-ego-map", "random-oracle-found"):
        assert (out / name / "eval-val" / "metrics.json").is_file(), name
    assert (out / "report" / "report.md").is_file()
    again = subprocess.run(script, cwd=tmp_path, env={**env, "PUBLISH": "1"},
                           capture_output=True, text=True, timeout=600)  # fmt: skip
    assert again.returncode == 0, again.stdout[-3000:] + again.stderr[-3000:]
    assert "done: oracle-map" in again.stdout and "== train" not in again.stdout
    kept = tmp_path / "docs" / "learned" / "central"
    assert (kept / "oracle-map" / "progress.csv").is_file()
    assert not (kept / "random-oracle-found" / "progress.csv").exists()
    text = doc.read_text()
    assert (
        "| oracle-map (oracle-map) | 1-ON | 2 |" in text
        and "| no-map (no-map) | 1-ON | 2 |" in text
    )
    # a fresh clone (no runs yet) goes on from the published runs instead of training again
    fresh = subprocess.run(script, cwd=tmp_path, env={**env, "OUT": "runs/fresh"},
                           capture_output=True, text=True, timeout=600)  # fmt: skip
    assert fresh.returncode == 0, fresh.stdout[-3000:] + fresh.stderr[-3000:]
    assert "== train" not in fresh.stdout and "== eval" not in fresh.stdout
    for name in ("oracle-map", "no-map", "oracle-ego-map", "random-oracle-found"):
        assert f"restored: {name}" in fresh.stdout, name
        restored = tmp_path / "runs" / "fresh" / name / "eval-val" / "metrics.json"
        assert restored.read_bytes() == (kept / name / "metrics.json").read_bytes()
    assert (tmp_path / "runs" / "fresh" / "oracle-map" / "progress.csv").is_file()
    assert (tmp_path / "runs" / "fresh" / "report" / "report.md").is_file()


def _copy_script(tmp_path: Path, name: str) -> None:
    """scripts/NAME into tmp_path/scripts, with the files the scripts source."""
    (tmp_path / "scripts").mkdir(exist_ok=True)
    for script in (name, "camera_variant.sh", "publish_run.sh"):
        shutil.copy(ROOT / "scripts" / script, tmp_path / "scripts")


# A stand-in for the `multion` command: it records each call and writes the files the script
# looks for, so the script's choices are checked in seconds, without training anything.
FAKE_MULTION = """#!/usr/bin/env bash
echo "$*" >> "$CALLS"
out=""
while [ $# -gt 0 ]; do
  if [ "$1" = --out ]; then out=$2; fi
  shift
done
if [ -n "$out" ]; then
  mkdir -p "$out"
  touch "$out/checkpoint.pt" "$out/metrics.json" "$out/episodes.jsonl" "$out/report.md"
fi
"""


def _stand_in(tmp_path: Path, variables: dict[str, str]) -> dict[str, str]:
    """The environment in which a script calls the stand-in command, which records each call in
    tmp_path/calls.txt (read by :func:`_calls`), with ``variables`` set."""
    fake = tmp_path / "fake_multion.sh"
    fake.write_text(FAKE_MULTION)
    return {**os.environ, "CALLS": str(tmp_path / "calls.txt"), "MULTION": f"bash {fake}",
            **variables}  # fmt: skip


def _calls(tmp_path: Path) -> list[str]:
    """The command lines the stand-in command was called with since the last one read, which
    are then forgotten."""
    calls = tmp_path / "calls.txt"
    if not calls.exists():
        return []
    lines = calls.read_text().splitlines()
    calls.unlink()
    return lines


def _script(tmp_path: Path, name: str, env: dict[str, str]) -> str:
    """Run scripts/NAME in tmp_path under ``env``; its stdout, once it has ended with 0."""
    done = subprocess.run(["bash", f"scripts/{name}"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout


def _central_calls(tmp_path: Path, variables: dict[str, str]) -> tuple[str, list[str]]:
    """Run scripts/central_comparison.sh's core stage with the stand-in command; its stdout
    and the command lines it ran."""
    _calls(tmp_path)
    env = _stand_in(tmp_path, {"STAGES": "core", "FRAMES": "1024", **variables})
    stdout = _script(tmp_path, "central_comparison.sh", env)
    return stdout, _calls(tmp_path)


def test_run_baselines_passes_eval_args_to_every_run(tmp_path: Path) -> None:
    """scripts/run_baselines.sh (issue 53 item 8): EVAL_ARGS reach every evaluation (explorer's
    runs with gl), EPISODES_OVERRIDE sets their size, and finished runs are kept."""
    (tmp_path / "scripts").mkdir()
    shutil.copy(ROOT / "scripts" / "run_baselines.sh", tmp_path / "scripts")
    env = _stand_in(tmp_path, {"EVAL_ARGS": "--set camera.renderer=gl", "EPISODES_OVERRIDE": "3"})
    script = ["bash", "scripts/run_baselines.sh", "runs", "explorer"]
    done = subprocess.run(script, cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=60)  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    evals = _calls(tmp_path)
    names = sorted(line.split("--out runs/")[1].split()[0] for line in evals)
    assert names == ["explorer-1on", "explorer-2on", "explorer-3on", "explorer-3on-distractors"]
    assert all("--episodes 3 " in e and "--set camera.renderer=gl --agent explorer" in e
               for e in evals)  # fmt: skip
    again = subprocess.run(script, cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=60)  # fmt: skip
    assert again.returncode == 0 and "already in runs" in again.stdout
    assert not _calls(tmp_path)


def test_central_comparison_has_a_128_variant_of_its_own(tmp_path: Path) -> None:
    """IMAGE_SIZE=128 RENDERER=gl (issue 44 item 3) trains and evaluates at that size with that
    renderer into runs/central-128-gl, never restores the published 36² runs into it, and reports
    beside them; without the variables the 36² recipe is unchanged."""
    _copy_script(tmp_path, "central_comparison.sh")
    published = tmp_path / "docs" / "learned" / "central" / "oracle-map"
    published.mkdir(parents=True)
    for name in ("metrics.json", "episodes.jsonl"):
        (published / name).write_text("{}\n")

    stdout, calls = _central_calls(tmp_path, {"IMAGE_SIZE": "128", "RENDERER": "gl"})
    trains = [c for c in calls if c.startswith("train ")]
    evals = [c for c in calls if c.startswith("eval ")]
    assert "restored" not in stdout
    assert len(trains) == 3 and len(evals) == 4  # oracle-map, no-map, oracle-ego-map (+ random)
    for call in trains:
        assert "--image-size 128 " in call and "--set camera.renderer=gl" in call, call
        assert "--out runs/central-128-gl/" in call, call
    assert all("--set camera.renderer=gl" in call for call in evals)
    report = next(c for c in calls if c.startswith("report "))
    assert "docs/learned/central " in report and "--out runs/central-128-gl/report" in report

    shutil.rmtree(tmp_path / "runs" / "central-128-gl")
    only = {"IMAGE_SIZE": "128", "RENDERER": "gl", "ONLY": "no-map oracle-map"}
    _, calls = _central_calls(tmp_path, only)
    assert [c.split()[:3] for c in calls if not c.startswith("report ")] == [
        ["train", "--agent", "oracle-map"], ["eval", "--agent", "oracle-map"],
        ["train", "--agent", "no-map"], ["eval", "--agent", "no-map"],
    ]  # fmt: skip

    stdout, calls = _central_calls(tmp_path, {})
    assert "restored: oracle-map" in stdout
    trains = [c for c in calls if c.startswith("train ")]
    assert len(trains) == 2  # oracle-map is published
    for call in trains:
        assert "--image-size 36 " in call and "camera.renderer" not in call, call
        assert "--out runs/central/" in call, call


def test_the_recipe_pilot_trains_each_option_alone_and_together(tmp_path: Path) -> None:
    """scripts/recipe_pilot.sh (issue 51) with the stand-in command: nine no-map runs at the
    central comparison's recipe, the FOUND curriculum over the first 40 % of the frames, each
    then evaluated; run again, it skips what is done."""
    _copy_script(tmp_path, "recipe_pilot.sh")
    env = _stand_in(tmp_path, {"FRAMES": "1000"})
    _script(tmp_path, "recipe_pilot.sh", env)
    lines = _calls(tmp_path)
    trains = [line for line in lines if line.startswith("train")]
    by_run = {line.split("--out ")[1].split()[0].rsplit("/", 1)[1]: line for line in trains}
    assert sorted(by_run) == sorted(
        [
            "no-map-all",
            "no-map-paper",
            "no-map-heads",
            "no-map-found-sup",
            "no-map-found",
            "no-map-vision",
            "no-map-all-sup",
            "no-map-found-sup-curricula",
            "no-map-found-sup10-curricula",
            "no-map-found-head-near",
            "no-map-found-head-vision",
            "no-map-found-head-free",
            "no-map-found-head-all",
            "no-map-found-head-smooth",
            "no-map-found-head-weighted",
            "no-map-found-head-coverage",
            "no-map-found-head-coverage-2.5",
            "no-map-found-head-long",
            "no-map-found-head-normalized",
            "no-map-found-head-policy-share",
            "no-map-found-head-explorer-imitation",
            "no-map-found-head-houses",
            "no-map-found-head-pose",
            "no-map-found-head-separate-critic",
            "no-map-found-head-image",
            "no-map-found-head-seen",
            "no-map-found-head-frozen",
        ]  # fmt: skip
    )
    assert "--found-head-reads-image" in by_run["no-map-found-head-image"]
    assert "--found-head-label seen" in by_run["no-map-found-head-seen"]
    assert not any("--found-head-label" in by_run[r] for r in by_run if "seen" not in r)
    assert by_run["no-map-found-head-frozen"].endswith("--pretrain-vision 2000 --freeze-vision")
    assert not any("--freeze-vision" in by_run[r] for r in by_run if "frozen" not in r)
    for line in trains:
        assert "--frames 1000" in line and "--found-prior 0.02" in line
    extras = ("--goal-heads", "--found-curriculum", "--pretrain-vision")
    assert not any(flag in by_run["no-map-paper"] for flag in extras)
    assert all(flag in by_run["no-map-all"] for flag in extras)
    assert "--found-curriculum 400:2.5" in by_run["no-map-all"]  # the reference's penalty
    assert "--found-curriculum 400:0.5" in by_run["no-map-found"]  # a fifth of it (FOUND_PENALTY)
    assert "--goal-heads" in by_run["no-map-heads"]
    assert "--found-curriculum" not in by_run["no-map-heads"]
    assert "--pretrain-vision 2000" in by_run["no-map-vision"]
    assert "--found-supervision 1" in by_run["no-map-found-sup"]
    assert all(flag in by_run["no-map-all-sup"] for flag in (*extras, "--found-supervision 1"))
    assert "--found-supervision" not in by_run["no-map-all"]
    assert "--normalize-advantages" in by_run["no-map-found-head-normalized"]
    assert not any("--normalize-advantages" in by_run[r] for r in by_run if "normalized" not in r)
    curricula = by_run["no-map-found-sup-curricula"]
    assert "--found-supervision 1 --curriculum 400:4 --curriculum 700:10" in curricula
    assert "--found-curriculum 400:0.5" in curricula
    assert "--found-supervision 10 --curriculum" in by_run["no-map-found-sup10-curricula"]
    near = by_run["no-map-found-head-near"]
    assert "--found-head 1 --curriculum 400:4 --curriculum 700:10" in near
    assert not any(flag in near for flag in (*extras, "--found-supervision"))
    assert all(
        flag in by_run["no-map-found-head-all"] for flag in ("--goal-heads", "--found-head 1")
    )
    evals = [line for line in lines if line.startswith("eval")]
    assert "--found-head 1" in by_run["no-map-found-head-vision"]
    assert "--pretrain-vision 2000" in by_run["no-map-found-head-vision"]
    assert "--found-curriculum 400:0" in by_run["no-map-found-head-free"]
    smooth = by_run["no-map-found-head-smooth"]
    assert "--found-head 1 --goal-heads --pretrain-vision 2000 --curriculum 200:4" in smooth
    assert "--curriculum 400:7 --curriculum 550:10 --curriculum 700:15" in smooth
    weighted = by_run["no-map-found-head-weighted"]
    assert "--goal-heads --pretrain-vision 2000 --found-head-positive-weight 10" in weighted
    coverage = by_run["no-map-found-head-coverage"]
    assert "--goal-heads --pretrain-vision 2000 --coverage-reward 0.25" in coverage
    assert "--coverage-reward 2.5" in by_run["no-map-found-head-coverage-2.5"]
    long = by_run["no-map-found-head-long"]
    assert "--max-steps 500" in long and long.endswith("--max-steps 2500")  # the last one wins
    share = by_run["no-map-found-head-policy-share"]
    assert "--goal-heads --pretrain-vision 2000 --value-coef 0.1 --goal-head-coef 0.05" in share
    assert not any("--value-coef" in by_run[r] for r in by_run if "policy-share" not in r)
    imitation = by_run["no-map-found-head-explorer-imitation"]
    assert "--found-head 1 --curriculum 400:4 --curriculum 700:10 --goal-heads" in imitation
    assert imitation.endswith("--pretrain-vision 2000 --imitation-coef 1 --expert explorer")
    houses = by_run["no-map-found-head-houses"]
    assert "--episodes-per-scene 200" in houses and houses.endswith("--episodes-per-scene 5")
    assert not any("--episodes-per-scene 5" in by_run[r] for r in by_run if "houses" not in r)
    assert by_run["no-map-found-head-pose"].endswith(
        "--goal-heads --pretrain-vision 2000 --pose-input"
    )
    assert not any("--pose-input" in by_run[r] for r in by_run if "pose" not in r)
    assert by_run["no-map-found-head-separate-critic"].endswith(
        "--goal-heads --pretrain-vision 2000 --separate-critic"
    )
    assert not any("--separate-critic" in by_run[r] for r in by_run if "critic" not in r)
    assert len(evals) == len(by_run) and all("--split val --episodes 100" in line for line in evals)
    assert "done: no-map-all" in _script(tmp_path, "recipe_pilot.sh", env)
    assert not any(line.startswith(("train", "eval")) for line in _calls(tmp_path))


def test_the_recipe_pilot_runs_the_options_on_another_agent(tmp_path: Path) -> None:
    """AGENT=proj-neural-map (or obj-recog-map) with ONLY trains and evaluates that agent with the
    run's options under its own name; obj-recog-map's runs add its balanced recogniser, as the
    learn-to-see recipe of the central comparison does, and no other agent's do."""
    _copy_script(tmp_path, "recipe_pilot.sh")
    for agent in ("proj-neural-map", "obj-recog-map"):
        variables = {"FRAMES": "1000", "AGENT": agent, "ONLY": f"{agent}-found-head-all"}
        _script(tmp_path, "recipe_pilot.sh", _stand_in(tmp_path, variables))
        lines = _calls(tmp_path)
        train, evaluation = (line for line in lines if line.startswith(("train", "eval")))
        assert train.startswith(f"train --agent {agent} ")
        assert f"--out runs/pilot/{agent}-found-head-all" in train
        assert "--found-head 1 --curriculum 400:4 --curriculum 700:10 --goal-heads" in train
        assert ("--balanced-recognition" in train) == (agent == "obj-recog-map"), train
        assert evaluation.startswith(f"eval --agent {agent} --checkpoint ")
    # the recogniser's pretraining is a pilot of obj-recog-map's only
    variables = {"FRAMES": "1000", "AGENT": "obj-recog-map",
                 "ONLY": "obj-recog-map-found-head-recogniser no-map-found-head-recogniser"}  # fmt: skip
    _script(tmp_path, "recipe_pilot.sh", _stand_in(tmp_path, variables))
    (train, _) = (line for line in _calls(tmp_path) if line.startswith(("train", "eval")))
    assert "--out runs/pilot/obj-recog-map-found-head-recogniser " in train
    assert train.endswith("--pretrain-vision 2000 --pretrain-recogniser")
    variables["ONLY"] = "obj-recog-map-found-head-recogniser-seen"
    _script(tmp_path, "recipe_pilot.sh", _stand_in(tmp_path, variables))
    (train, _) = (line for line in _calls(tmp_path) if line.startswith(("train", "eval")))
    assert train.endswith("--pretrain-recogniser --found-head-label seen")


def test_the_recipe_pilot_runs_a_variant_at_another_image_size(tmp_path: Path) -> None:
    """IMAGE_SIZE=128 RENDERER=gl trains and evaluates under the run's name with -128-gl appended,
    at that size with that renderer, and a 36² run of the same options is neither resumed nor
    taken for it."""
    _copy_script(tmp_path, "recipe_pilot.sh")
    done_36 = tmp_path / "runs" / "pilot" / "no-map-found-head-all" / "eval-val"
    done_36.mkdir(parents=True)
    (done_36 / "metrics.json").write_text("{}")
    (done_36.parent / "checkpoint.pt").write_text("")
    variables = {"FRAMES": "1000", "IMAGE_SIZE": "128", "RENDERER": "gl",
                 "ONLY": "no-map-found-head-all-128-gl"}  # fmt: skip
    _script(tmp_path, "recipe_pilot.sh", _stand_in(tmp_path, variables))
    lines = _calls(tmp_path)
    train, evaluation = (line for line in lines if line.startswith(("train", "eval")))
    assert "--out runs/pilot/no-map-found-head-all-128-gl " in train + " "
    assert "--image-size 128 " in train and "--image-size 36" not in train
    assert "--set camera.renderer=gl" in train and "--resume" not in train
    assert "--found-head 1 --curriculum 400:4 --curriculum 700:10 --goal-heads" in train
    assert "--set camera.renderer=gl" in evaluation
    assert "--checkpoint runs/pilot/no-map-found-head-all-128-gl/checkpoint.pt" in evaluation


def test_central_comparison_runs_issue_51s_recipe_as_a_variant(tmp_path: Path) -> None:
    """RECIPE=learn-to-see trains every agent with the options beyond the paper at 3M frames
    (near goals over the first 200k, as in its pilot), obj-recog-map with its balanced recogniser
    pretrained on rendered frames, into
    runs/central-learn-to-see, reported beside the paper's published runs; an unknown recipe is
    refused."""
    _copy_script(tmp_path, "central_comparison.sh")
    (tmp_path / "docs" / "learned" / "central").mkdir(parents=True)
    variables = {"RECIPE": "learn-to-see", "STAGES": "core learned", "FRAMES": ""}
    _, calls = _central_calls(tmp_path, variables)
    trains = {c.split()[2]: c for c in calls if c.startswith("train ")}
    assert sorted(trains) == ["no-map", "obj-recog-map", "oracle-ego-map", "oracle-map",
                              "proj-neural-map"]  # fmt: skip
    for agent, call in trains.items():
        assert "--frames 3000000 " in call and "--out runs/central-learn-to-see/" in call
        assert "--found-head 1 --goal-heads --pretrain-vision 2000 --curriculum 200000:4" in call
        assert "--curriculum 350000:10" in call and "--found-curriculum" not in call
        recognises = agent == "obj-recog-map"
        assert ("--balanced-recognition --pretrain-recogniser" in call) == recognises, call
        assert ("--pretrain-recogniser" in call) == recognises, call
    report = next(c for c in calls if c.startswith("report "))
    assert "docs/learned/central " in report
    # at the paper runs' 720k frames: a variant of its own, beside the 3M one
    _, calls = _central_calls(tmp_path, {**variables, "FRAMES": "720000", "ONLY": "no-map"})
    (train,) = [c for c in calls if c.startswith("train ")]
    assert "--frames 720000 " in train and "--out runs/central-learn-to-see-720k/no-map" in train
    assert "--found-head 1 --goal-heads" in train
    # at 128² with gl: reported beside the 36² paper runs, the 128² paper runs and the recipe's
    # 36² runs, where they are published, and not beside itself
    for kept in ("central-128-gl", "central-learn-to-see-720k", "central-128-gl-learn-to-see-720k"):
        (tmp_path / "docs" / "learned" / kept).mkdir()
    camera = {"IMAGE_SIZE": "128", "RENDERER": "gl"}
    _, calls = _central_calls(
        tmp_path, {**variables, **camera, "FRAMES": "720000", "ONLY": "no-map"}
    )
    (train,) = [c for c in calls if c.startswith("train ")]
    assert "--out runs/central-128-gl-learn-to-see-720k/no-map " in train
    report = next(c for c in calls if c.startswith("report "))
    assert report.split(" --out ")[0].split()[-3:] == [
        "docs/learned/central", "docs/learned/central-128-gl",
        "docs/learned/central-learn-to-see-720k",
    ]  # fmt: skip
    paper = subprocess.run(["bash", "scripts/central_comparison.sh"], cwd=tmp_path,
                           env={**os.environ, "RECIPE": "mine"}, capture_output=True, text=True,
                           timeout=60)  # fmt: skip
    assert paper.returncode == 2 and "unknown RECIPE mine (paper, learn-to-see)" in paper.stderr


def test_the_found_gate_sweep_plays_each_gate_on_train_houses_once(tmp_path: Path) -> None:
    """scripts/found_gate_sweep.sh makes a train-split dataset, plays the checkpoint at each gate
    on it (never on val) with the renderer given, reports the gates side by side, and skips a
    gate already played when run again."""
    _copy_script(tmp_path, "found_gate_sweep.sh")
    env = _stand_in(tmp_path, {"AGENT": "no-map", "CHECKPOINT": "runs/x/checkpoint.pt",
                               "RENDERER": "gl", "GATES": "0.5 0.8", "EPISODES": "7"})  # fmt: skip
    _script(tmp_path, "found_gate_sweep.sh", env)
    generate, *evaluations, report = _calls(tmp_path)
    assert generate.startswith("dataset generate --task 1-on --split train --episodes 7 --seed 51")
    assert [line.split("--found-gate ")[1].split()[0] for line in evaluations] == ["0.5", "0.8"]
    for line in evaluations:
        assert "--split train --dataset runs/gate/train-1on-7.json.gz" in line
        assert "--checkpoint runs/x/checkpoint.pt" in line and "--set camera.renderer=gl" in line
        assert "--split val" not in line
    assert report.startswith(
        "report runs/gate/x/gate-0.5 runs/gate/x/gate-0.8 --out runs/gate/x/report"
    )
    again = _script(tmp_path, "found_gate_sweep.sh", {**env, "GATES": "0.5 0.8 0.9"})
    assert "done: gate 0.5" in again
    (evaluation,) = (line for line in _calls(tmp_path) if line.startswith("eval"))
    assert "--found-gate 0.9" in evaluation


def test_central_comparison_plays_each_run_at_a_found_gate_too(tmp_path: Path) -> None:
    """FOUND_GATE=0.8 with a recipe that has the FOUND head: each trained run is also played on
    the same val episodes at that gate from its checkpoint, as NAME-gate-0.8, once; the report
    (and the published one) pairs it with NAME; a run with no checkpoint here is not played at
    the gate; the paper's recipe, which has no FOUND head, refuses the variable."""
    _copy_script(tmp_path, "central_comparison.sh")
    out = "runs/central-learn-to-see-720k"
    variables = {"RECIPE": "learn-to-see", "STAGES": "core", "FRAMES": "720000", "ONLY": "no-map",
                 "FOUND_GATE": "0.8"}  # fmt: skip
    _, calls = _central_calls(tmp_path, variables)
    train, plain, gated, report = calls
    assert train.startswith("train --agent no-map ") and "--found-head 1" in train
    assert plain.startswith("eval --agent no-map ") and "--found-gate" not in plain
    assert gated.startswith("eval --agent no-map --checkpoint " + f"{out}/no-map/checkpoint.pt ")
    assert "--split val --episodes 100 --workers 2 --seed 0" in gated
    assert gated.endswith(f"--found-gate 0.8 --out {out}/no-map-gate-0.8/eval-val")
    assert report.endswith(
        f"--pair {out}/no-map-gate-0.8/eval-val {out}/no-map/eval-val --out {out}/report"
    )

    stdout, calls = _central_calls(tmp_path, {**variables, "PUBLISH": "1"})
    assert "done: no-map-gate-0.8" in stdout
    # nothing played again; each run gains the task's newer measures before it is kept
    assert [call.split()[0] for call in calls] == ["report", "rescore", "rescore", "report"]
    assert sorted(calls[1:3]) == [f"rescore --quiet {out}/no-map-gate-0.8/eval-val",
                                  f"rescore --quiet {out}/no-map/eval-val"]  # fmt: skip
    kept = "docs/learned/central-learn-to-see-720k"
    assert (tmp_path / kept / "no-map-gate-0.8" / "metrics.json").is_file()
    assert f"--pair {kept}/no-map-gate-0.8 {kept}/no-map --out {kept}/report" in calls[3]

    shutil.rmtree(tmp_path / kept / "no-map-gate-0.8")
    stdout, calls = _central_calls(tmp_path, {**variables, "OUT": "runs/fresh"})
    assert "restored: no-map (published" in stdout
    assert "skipped: no-map-gate-0.8 (no runs/fresh/no-map/checkpoint.pt to play)" in stdout
    assert [call.split()[0] for call in calls] == ["report"] and "--pair" not in calls[0]

    paper = subprocess.run(["bash", "scripts/central_comparison.sh"], cwd=tmp_path,
                           env={**os.environ, "FOUND_GATE": "0.8"}, capture_output=True,
                           text=True, timeout=60)  # fmt: skip
    assert (
        paper.returncode == 2 and "FOUND_GATE is for a recipe with the FOUND head" in paper.stderr
    )
