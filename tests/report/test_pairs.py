"""``multion report --pair A B``: two runs compared on the episodes both played whatever their
conditions, with what differs named; a name that picks no run, or more than one, is refused."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_report import _with_camera, copy_run, episodes, read_csv, report

METRICS = ("success", "progress", "spl", "ppl")


def test_a_requested_pair_across_conditions_equals_the_hand_computed_difference(
    report_runs: Path, tmp_path: Path
) -> None:
    """random with found budget 2 against 0: never in the paired table (their conditions
    differ), in the requested one with the budget named."""
    budget2, budget0 = report_runs / "random-2on-budget2", report_runs / "random-2on"
    out = tmp_path / "out"
    argv = [str(report_runs), "--out", str(out), "--no-figures"]
    assert report([*argv, "--pair", "random-2on-budget2", str(budget0)]) == 0
    (row,) = read_csv(out / "requested-pairs.csv")
    assert (row["run_a"], row["run_b"]) == ("random-2on-budget2", "random-2on")
    assert row["differs_in"] == "found budget: 2 vs 0"
    a = {e["episode_id"]: e["metrics"] for e in episodes(budget2)}
    b = {e["episode_id"]: e["metrics"] for e in episodes(budget0)}
    assert int(row["common_episodes"]) == len(a)
    for metric in METRICS:
        by_hand = 100 * sum(a[i][metric] - b[i][metric] for i in a) / len(a)
        assert float(row[f"diff_{metric}"]) == pytest.approx(by_hand, abs=1e-3)
    paired = {(r["run_a"], r["run_b"]) for r in read_csv(out / "paired.csv")}
    assert not any("random-2on-budget2" in pair for pair in paired)
    text = (out / "report.md").read_text()
    assert "Pairs asked for (`--pair`)" in text
    assert f"--pair random-2on-budget2 {budget0}" in text  # the command to make it again
    # without --pair there is no such table
    plain = tmp_path / "plain"
    assert report([str(report_runs), "--out", str(plain), "--no-figures"]) == 0
    assert not (plain / "requested-pairs.csv").exists()


def test_a_requested_pair_names_the_cameras_that_differ(report_runs: Path, tmp_path: Path) -> None:
    """A 128² pilot against another directory's 36² baseline: what the scripts' published
    figures pair by hand. Runs of one name in two directories are told apart by their parent."""
    source = report_runs / "random-oracle-found-2on"
    large = _with_camera(source, tmp_path / "pilot" / "x-128-gl", 128, "gl", trained="x-128-gl")
    small = _with_camera(source, tmp_path / "central" / "x", 36, None, trained="x")
    twin = copy_run(small, tmp_path / "central-other" / "x")
    out = tmp_path / "out"
    argv = [str(large), str(small), str(twin), "--out", str(out), "--no-figures"]
    assert (
        report([*argv, "--pair", "x-128-gl", "central/x", "--pair", "central/x", "x-128-gl"]) == 0
    )
    rows = read_csv(out / "requested-pairs.csv")
    assert [(r["run_a"], r["run_b"]) for r in rows] == [("x-128-gl", "x"), ("x", "x-128-gl")]
    assert rows[0]["differs_in"] == "camera: 128² (gl) vs 36² (tiny)"
    assert float(rows[0]["diff_success"]) == -float(rows[1]["diff_success"])
    assert "central-other" not in rows[0]["b"]


@pytest.mark.parametrize(
    ("pair", "message"),
    [
        (["nowhere", "random-2on"], "--pair nowhere: no run of the report has that directory"),
        (["x", "random-2on"], "--pair x: 2 runs' directories end so"),
        (["random-2on", "runs/random-2on"], "both name"),
    ],
)
def test_a_pair_that_names_no_single_run_is_refused_before_anything_is_written(
    report_runs: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    pair: list[str],
    message: str,
) -> None:
    for parent in ("a", "b"):
        copy_run(report_runs / "random-2on", tmp_path / parent / "x")
    copy_run(report_runs / "random-2on", tmp_path / "runs" / "random-2on")
    out = tmp_path / "out"
    runs = [str(tmp_path / "a"), str(tmp_path / "b"), str(tmp_path / "runs")]
    assert report([*runs, "--out", str(out), "--no-figures", "--pair", *pair]) == 2
    error = capsys.readouterr().err
    assert message in error
    assert not out.exists()
    if "no run" in message:
        assert "random-2on" in error.split("runs:", 1)[1]  # the names there are


def test_the_pair_option_takes_two_runs(
    report_runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exited:
        report([str(report_runs), "--out", str(tmp_path / "out"), "--pair", "random-2on"])
    assert exited.value.code == 2
    assert "--pair: expected 2 arguments" in capsys.readouterr().err


def test_a_requested_pair_names_the_agents_settings_that_differ(
    report_runs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One checkpoint played at two FOUND gates (``run.agent_settings``): the gates are what
    differs; a run whose agent_settings is not an object is refused, naming the field."""
    source = report_runs / "random-oracle-found-2on"
    high = copy_run(source, tmp_path / "gate-0.8", agent_settings={"found_gate": 0.8})
    low = copy_run(source, tmp_path / "gate-0.5", agent_settings={"found_gate": 0.5})
    out = tmp_path / "out"
    argv = [
        str(high),
        str(low),
        "--out",
        str(out),
        "--no-figures",
        "--pair",
        "gate-0.8",
        "gate-0.5",
    ]
    assert report(argv) == 0
    (row,) = read_csv(out / "requested-pairs.csv")
    assert row["differs_in"] == "agent: found_gate=0.8 vs found_gate=0.5"
    copy_run(source, tmp_path / "broken", agent_settings=[0.8])
    broken = [str(tmp_path / "broken"), "--out", str(tmp_path / "out2"), "--no-figures"]
    assert report(broken) == 2
    assert "'run.agent_settings' is not an object" in capsys.readouterr().err
