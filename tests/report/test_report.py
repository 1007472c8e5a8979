"""``multion report`` over small real runs: numbers equal hand computations from episodes.jsonl."""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from multion_agents import cli_eval, cli_report
from multion_agents.report.document import BEGIN, END

METRICS = ("success", "progress", "spl", "ppl")


def run_eval(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    return cli_eval.run(parser.parse_args(argv))


def report(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    cli_report.add_arguments(parser)
    return cli_report.run(parser.parse_args(argv))


def episodes(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def copy_run(source: Path, target: Path, **run_changes: object) -> Path:
    shutil.copytree(source, target)
    if run_changes:
        payload = json.loads((target / "metrics.json").read_text())
        payload["run"].update(run_changes)
        (target / "metrics.json").write_text(json.dumps(payload))
    return target


@pytest.fixture(scope="module")
def full_report(report_runs: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report-out")
    assert report([str(report_runs), "--out", str(out)]) == 0
    return out


def test_table3_equals_hand_computed_means(report_runs: Path, full_report: Path) -> None:
    rows = {(r["run"]): r for r in read_csv(full_report / "table3.csv")}
    assert len(rows) == 6
    for name in ("oracle-planner-1on", "oracle-planner-2on", "random-oracle-found-2on"):
        played = episodes(report_runs / name)
        row = rows[name]
        assert int(row["episodes"]) == len(played)
        for metric in METRICS:
            by_hand = 100 * sum(e["metrics"][metric] for e in played) / len(played)
            assert float(row[metric]) == pytest.approx(by_hand, abs=1e-3)
            assert float(row[f"{metric}_low"]) <= float(row[metric]) <= float(row[f"{metric}_high"])
    # the paper's numbers sit beside the agents that have a counterpart, and only those
    assert rows["random-oracle-found-2on"]["paper_success"] == "8.0"
    assert rows["oracle-planner-1on"]["paper_success"] == ""
    text = (full_report / "report.md").read_text()
    assert "26 / 26 / 8 / 8 (Rand+OracleFound)" in text


def test_seen_not_seen_equals_hand_split(report_runs: Path, full_report: Path) -> None:
    rows = {r["run"]: r for r in read_csv(full_report / "seen-not-seen.csv")}
    for name in ("oracle-planner-2on", "random-oracle-found-2on"):
        played = [e["metrics"] for e in episodes(report_runs / name)]
        reached = [
            m for m in played if m["goals_found"] >= 1
        ]  # goal 1 found: goal 2 was looked for
        seen = [float(m["goals_found"] >= 2) for m in reached if m["seen_before_current"][0]]
        unseen = [float(m["goals_found"] >= 2) for m in reached if not m["seen_before_current"][0]]
        row = rows[name]
        assert row["goal"] == "2"
        assert int(row["seen_episodes"]) == len(seen)
        assert int(row["not_seen_episodes"]) == len(unseen)
        if seen:
            assert float(row["seen"]) == pytest.approx(100 * np.mean(seen))
        if unseen:
            assert float(row["not_seen"]) == pytest.approx(100 * np.mean(unseen))
        if seen and unseen:
            assert float(row["improvement"]) == pytest.approx(
                100 * (np.mean(seen) - np.mean(unseen))
            )


def test_paired_differences_equal_hand_computed(report_runs: Path, full_report: Path) -> None:
    rows = read_csv(full_report / "paired.csv")
    pairs = {(r["run_a"], r["run_b"]): r for r in rows}
    row = pairs[("random-oracle-found-2on", "oracle-planner-2on")]
    a = {e["episode_id"]: e["metrics"] for e in episodes(report_runs / "random-oracle-found-2on")}
    b = {e["episode_id"]: e["metrics"] for e in episodes(report_runs / "oracle-planner-2on")}
    assert int(row["common_episodes"]) == len(a) == len(b)
    for metric in METRICS:
        by_hand = 100 * np.mean([a[i][metric] - b[i][metric] for i in a])
        assert float(row[f"diff_{metric}"]) == pytest.approx(by_hand, abs=1e-3)
    # runs under different conditions (found budget 2 vs 0) are never paired
    assert not any("random-2on-budget2" in key for key in pairs)
    assert ("oracle-planner-1on", "oracle-planner-2on") not in pairs


def test_found_budget_table(full_report: Path) -> None:
    rows = read_csv(full_report / "found-budget.csv")
    assert [(r["run"], r["found_budget"]) for r in rows] == [
        ("random-2on", "0"),
        ("random-2on-budget2", "2"),
    ]
    for row in rows:
        assert int(row["episodes"]) == 4


def test_eval_set_is_recorded(report_runs: Path) -> None:
    run = json.loads(((report_runs / "random-2on-budget2") / "metrics.json").read_text())["run"]
    assert run["env_overrides"] == {"task": {"found_budget": 2}}
    assert run["resolved_config"]["task"]["found_budget"] == 2
    assert run["env_config"]["task"]["found_budget"] == 2
    plain = json.loads(((report_runs / "random-2on") / "metrics.json").read_text())["run"]
    assert plain["resolved_config"]["task"]["found_budget"] == 0
    assert len(plain["dataset_sha256"]) == 64
    # a found budget lets `random` survive wrong FOUNDs: its episodes get longer
    assert sum(e["metrics"]["steps"] for e in episodes(report_runs / "random-2on-budget2")) > sum(
        e["metrics"]["steps"] for e in episodes(report_runs / "random-2on")
    )


def test_agent_against_itself_is_exactly_zero(report_runs: Path, tmp_path: Path) -> None:
    twin = copy_run((report_runs / "random-oracle-found-2on"), tmp_path / "twin")
    out = tmp_path / "out"
    assert report([str(report_runs / "random-oracle-found-2on"), str(twin), "--out", str(out)]) == 0
    (row,) = read_csv(out / "paired.csv")
    for metric in METRICS:
        for suffix in ("", "_low", "_high"):
            assert float(row[f"diff_{metric}{suffix}"]) == 0.0
    # two runs of one agent under one condition are both shown, told apart by directory
    labels = [r["agent"] for r in read_csv(out / "table3.csv")]
    assert labels == ["random-oracle-found [random-oracle-found-2on]", "random-oracle-found [twin]"]


def test_mismatched_runs_are_flagged_not_merged(report_runs: Path, tmp_path: Path) -> None:
    other_split = copy_run(
        (report_runs / "oracle-planner-2on"), tmp_path / "op-2on-test", split="test"
    )
    other_data = copy_run(
        (report_runs / "random-oracle-found-2on"), tmp_path / "rof-2on-v2", dataset_sha256="f" * 64
    )
    fewer = tmp_path / "rof-1on-fewer"
    shutil.copytree((report_runs / "random-oracle-found-1on"), fewer)
    lines = (fewer / "episodes.jsonl").read_text().splitlines()
    (fewer / "episodes.jsonl").write_text("\n".join(lines[:2]) + "\n")
    payload = json.loads((fewer / "metrics.json").read_text())
    payload["run"]["episodes"] = 2
    (fewer / "metrics.json").write_text(json.dumps(payload))
    runs = [
        (report_runs / "oracle-planner-2on"),
        other_split,
        (report_runs / "random-oracle-found-2on"),
    ]
    runs += [other_data, (report_runs / "random-oracle-found-1on"), fewer]
    out = tmp_path / "out"
    assert report([*map(str, runs), "--out", str(out)]) == 0
    rows = read_csv(out / "table3.csv")
    assert len(rows) == 6  # nothing merged
    labels = {r["run"]: r["agent"] for r in rows}
    assert labels["op-2on-test"] == "oracle-planner (split test)"
    assert labels["rof-2on-v2"] == "random-oracle-found (dataset ffffffffffff)"
    text = (out / "report.md").read_text()
    assert "**Runs differ in split**" in text and "**Runs differ in dataset**" in text
    assert "**Episode counts differ**" in text and "2: rof-1on-fewer" in text
    # the split and dataset mismatches are not paired with the originals
    pairs = {(r["run_a"], r["run_b"]) for r in read_csv(out / "paired.csv")}
    assert pairs == {("random-oracle-found-2on", "oracle-planner-2on")} | {
        ("random-oracle-found-1on", "rof-1on-fewer")
    }


def test_bad_directories_get_clear_errors(
    report_runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = str(report_runs / "oracle-planner-1on")
    empty = tmp_path / "empty"
    empty.mkdir()
    corrupt = copy_run((report_runs / "oracle-planner-1on"), tmp_path / "corrupt")
    (corrupt / "metrics.json").write_text("{not json")
    truncated = copy_run((report_runs / "oracle-planner-2on"), tmp_path / "truncated")
    (truncated / "episodes.jsonl").write_text(
        (truncated / "episodes.jsonl").read_text().splitlines()[0] + "\n"
    )
    cases = [
        (tmp_path / "missing", "not a directory"),
        (empty, "no metrics.json here or in its subdirectories"),
        (corrupt, "metrics.json: not valid JSON"),
        (truncated, "metrics.json says 4 episodes but episodes.jsonl has 1"),
    ]
    for bad, message in cases:
        out = tmp_path / f"out-{bad.name}"
        assert report([good, str(bad), "--out", str(out)]) == 2
        error = capsys.readouterr().err
        assert message in error and str(bad) in error
        assert not out.exists()  # nothing half-written


def test_figures_are_written(full_report: Path) -> None:
    for name in ("metrics-vs-m.png", "episode-lengths.png"):
        with Image.open(full_report / name) as image:
            image.verify()
            assert image.size[0] > 600 and image.size[1] > 300
    text = (full_report / "report.md").read_text()
    assert "![Metrics against m](metrics-vs-m.png)" in text


def test_episode_lengths_make_room_for_long_run_names(report_runs: Path, tmp_path: Path) -> None:
    """Run names up to ~90 characters (a comparison's directories) get their own width: the
    panel keeps its size instead of constrained layout squeezing it away (and cutting them)."""
    source = report_runs / "random-oracle-found-2on"
    widths = {}
    for name in ("a", "a-comparison-published-under-a-long-directory-name-at-128-with-gl-720k"):
        twin = copy_run(source, tmp_path / name)
        out = tmp_path / f"out-{name}"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert report([str(source), str(twin), "--out", str(out)]) == 0
        assert not [w for w in caught if "constrained_layout" in str(w.message)]
        with Image.open(out / "episode-lengths.png") as image:
            widths[name] = image.size[0]
    short, long = widths.values()
    assert long > short


def test_doc_mode_replaces_only_the_generated_part(
    report_runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = tmp_path / "baselines.md"
    doc.write_text(f"# Baselines\n\nHand-written intro.\n\n{BEGIN}\nold table\n{END}\n\nOutro.\n")
    run = str(report_runs / "oracle-planner-1on")
    argv = [run, "--out", str(tmp_path), "--doc", "baselines", "--no-figures"]
    assert report(argv) == 0
    text = doc.read_text()
    assert text.startswith("# Baselines\n\nHand-written intro.\n\n" + BEGIN)
    assert text.endswith(END + "\n\nOutro.\n")
    assert "old table" not in text and "| oracle-planner | 1-ON | 4 |" in text
    assert "(baselines/table3.csv)" in text and (tmp_path / "baselines" / "table3.csv").exists()

    doc.write_text("# No markers\n")
    assert report(argv) == 2
    assert "has no generated part" in capsys.readouterr().err
    assert doc.read_text() == "# No markers\n"


def test_eval_set_errors(capsys: pytest.CaptureFixture[str]) -> None:
    for argv, message in [
        (["--set", "task.found_budget"], "expected SECTION.FIELD=VALUE"),
        (["--set", "task.num_goals=2"], "give the number of goals with --task"),
        (["--set", "task.found_budget=-3"], "task.found_budget = -3 is out of range"),
        (["--set", "task.found_bugdet=3"], "unknown field 'task.found_bugdet'"),
    ]:
        assert run_eval(["--agent", "random", "--quiet", *argv]) == 2
        assert message in capsys.readouterr().err


def test_missing_matplotlib_is_named(
    report_runs: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(cli_report, "has_matplotlib", lambda: False)
    run = str(report_runs / "oracle-planner-1on")
    assert report([run, "--out", str(tmp_path / "a")]) == 2
    assert "pip install 'multion-pybullet[report]'" in capsys.readouterr().err
    assert report([run, "--out", str(tmp_path / "b"), "--no-figures"]) == 0
    assert (tmp_path / "b" / "table3.csv").exists()


def test_runs_from_before_eval_set_still_load(report_runs: Path, tmp_path: Path) -> None:
    """Runs written before `multion eval` recorded the resolved config and dataset checksum."""
    from multion_agents.report.runs import load_run

    old = copy_run(report_runs / "random-2on-budget2", tmp_path / "old")
    payload = json.loads((old / "metrics.json").read_text())
    for key in ("resolved_config", "dataset_sha256", "env_overrides", "max_steps", "image_size"):
        del payload["run"][key]
    (old / "metrics.json").write_text(json.dumps(payload))
    run = load_run(old)
    assert run.found_budget == 2  # from the config sent to the environment
    assert run.dataset.endswith("room-2-on.json.gz")  # the --dataset path stands in for it
    assert run.other_settings == "camera.width=16, task.max_steps=80"


def test_a_run_reads_the_success_distance_it_was_played_with(
    report_runs: Path, tmp_path: Path
) -> None:
    """``search-or-stop`` counts "within reach" with the run's own ``task.success_distance``."""
    from multion_agents.report.runs import load_run

    assert load_run(report_runs / "oracle-planner-1on").success_distance == 1.5
    changed = copy_run(report_runs / "oracle-planner-1on", tmp_path / "near")
    payload = json.loads((changed / "metrics.json").read_text())
    payload["run"]["resolved_config"]["task"]["success_distance"] = 1.0
    (changed / "metrics.json").write_text(json.dumps(payload))
    assert load_run(changed).success_distance == 1.0


def test_train_and_eval_share_the_set_parser(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("torch")
    from multion_agents.cli import main

    assert (
        main(["train", "--set", "task.found_budget", "--frames", "64", "--out", str(tmp_path)]) == 2
    )
    assert "expected SECTION.FIELD=VALUE" in capsys.readouterr().err


def test_the_recorded_command_names_paths_from_the_working_directory(
    report_runs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A report made from absolute paths under the working directory records them relative to
    it, so a committed report names no directory of the machine that made it (issue 42)."""
    copy_run(report_runs / "oracle-planner-1on", tmp_path / "runs" / "op")
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "reports" / "op"
    assert report([str(tmp_path / "runs" / "op"), "--out", str(out), "--no-figures"]) == 0
    text = (out / "report.md").read_text()
    assert "Generated by `multion report runs/op --out reports/op --no-figures`" in text
    assert str(tmp_path) not in text


def _with_camera(
    source: Path, target: Path, size: int, renderer: str | None, trained: str | None = None
) -> Path:
    """A copy of a run as if it had been played at ``size``² with ``renderer`` (as `multion
    eval` records it: the resolved camera, and the renderer among the overrides when set), by
    the checkpoint of training run ``trained`` when given."""
    run = copy_run(source, target)
    payload = json.loads((run / "metrics.json").read_text())
    if trained is not None:
        payload["run"]["checkpoint"] = f"runs/{trained}/checkpoint.pt"
    camera = payload["run"]["resolved_config"]["camera"]
    camera.update(width=size, height=size, renderer=renderer or "tiny")
    if renderer is not None:
        payload["run"].setdefault("env_overrides", {}).setdefault("camera", {})["renderer"] = (
            renderer
        )
    (run / "metrics.json").write_text(json.dumps(payload))
    return run


def _camera_rows(runs: list[Path], out: Path) -> list[tuple[str, str]]:
    """The report's camera table over ``runs``: (run, camera) of each row."""
    assert report([*map(str, runs), "--out", str(out), "--no-figures"]) == 0
    return [(r["run"], r["camera"]) for r in read_csv(out / "cameras.csv")]


def test_runs_differing_only_in_the_camera_are_paired_by_camera(
    report_runs: Path, tmp_path: Path
) -> None:
    """Issue 44's 128² runs against the 36² ones: one agent at two cameras side by side with
    the paired difference; two agents at 128² compared in the paired table, and no agent at
    one camera against another agent at the other."""
    source = report_runs / "random-oracle-found-2on"
    small = _with_camera(source, tmp_path / "runs" / "a-36", 36, None)
    large = _with_camera(source, tmp_path / "runs" / "a-128", 128, "gl")
    other = _with_camera(report_runs / "oracle-planner-2on", tmp_path / "runs" / "b-128", 128, "gl")
    # the 128² run succeeds in its first two episodes
    played = episodes(large)
    for e in played[:2]:
        e["metrics"]["success"] = 1.0
    (large / "episodes.jsonl").write_text("".join(json.dumps(e) + "\n" for e in played))
    out = tmp_path / "out"
    assert report([str(small), str(large), str(other), "--out", str(out), "--no-figures"]) == 0

    rows = read_csv(out / "cameras.csv")
    assert [r["camera"] for r in rows] == [
        "36² (tiny)",
        "128² (gl)",
        "128² (gl) − 36² (tiny) (paired)",
    ]
    before = [e["metrics"]["success"] for e in episodes(small)]
    after = [e["metrics"]["success"] for e in played]
    by_hand = 100 * (sum(after) - sum(before)) / len(before)
    assert float(rows[2]["diff_success"]) == pytest.approx(by_hand, abs=1e-3)
    assert by_hand > 0
    pairs = {(r["run_a"], r["run_b"]) for r in read_csv(out / "paired.csv")}
    assert pairs == {("b-128", "a-128")} or pairs == {("a-128", "b-128")}


def test_checkpoints_of_differently_named_training_runs_are_not_paired_by_camera(
    report_runs: Path, tmp_path: Path
) -> None:
    """A 36² run of another recipe (``oracle-map-pretrained`` beside ``oracle-map``) is another
    agent: only the training runs of one name are compared across cameras."""
    source = report_runs / "random-oracle-found-2on"
    runs = [
        _with_camera(source, tmp_path / "runs" / name, size, renderer, trained)
        for name, size, renderer, trained in (
            ("x-36", 36, None, "x"), ("x-128", 128, "gl", "x"),
            ("x-pretrained-36", 36, None, "x-pretrained"),
        )
    ]  # fmt: skip
    assert _camera_rows(runs, tmp_path / "out") == [
        ("x-36", "36² (tiny)"),
        ("x-128", "128² (gl)"),
        ("x-128 − x-36", "128² (gl) − 36² (tiny) (paired)"),
    ]


def test_a_training_run_named_for_its_camera_pairs_with_the_run_it_varies(
    report_runs: Path, tmp_path: Path
) -> None:
    """scripts/recipe_pilot.sh names a 128² gl variant ``NAME-128-gl``: its checkpoint pairs with
    ``NAME``'s across cameras; a name ending in another camera's size is another run."""
    source = report_runs / "random-oracle-found-2on"
    runs = [
        _with_camera(source, tmp_path / "runs" / name, size, renderer, trained=name)
        for name, size, renderer in (("x", 36, None), ("x-128-gl", 128, "gl"), ("x-64", 128, "gl"))
    ]
    assert _camera_rows(runs, tmp_path / "out") == [
        ("x", "36² (tiny)"),
        ("x-128-gl", "128² (gl)"),
        ("x-128-gl − x", "128² (gl) − 36² (tiny) (paired)"),
    ]


def test_runs_of_one_name_in_two_directories_are_told_apart_by_their_parents(
    report_runs: Path, tmp_path: Path
) -> None:
    # a recipe's comparison beside the paper's: both directories hold a run called `rof`
    runs = [
        copy_run(report_runs / "random-oracle-found-2on", tmp_path / parent / "rof")
        for parent in ("central", "central-learn-to-see")
    ]
    out = tmp_path / "out"
    assert report([*map(str, runs), "--out", str(out)]) == 0
    labels = [r["agent"] for r in read_csv(out / "table3.csv")]
    assert sorted(labels) == [
        "random-oracle-found [central-learn-to-see/rof]",
        "random-oracle-found [central/rof]",
    ]
