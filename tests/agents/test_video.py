"""Episode videos: ``multion eval --video N`` and ``multion video RUN_DIR --episode ID``.

Frames come from the recorded actions replayed: the same run gives the same frames, the replay
must reproduce the recorded metrics, and the MP4 decodes to the stated number of frames."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
from pathlib import Path

import av
import numpy as np
import pytest

from multion.config.episode import Episode
from multion.video.encoder import read_frames, size_bound
from multion.video.stored import END_HOLD, FOUND_HOLD, MAX_VIDEO_FRAMES
from multion_agents import cli_eval, cli_video
from multion_agents.eval_settings import EvalSettings
from multion_agents.evaluate import evaluate
from multion_agents.video.film import MAX_VIDEOS
from multion_agents.video.recorded import VideoError, read_run, replay, replay_env

MAX_STEPS = 30


def _eval(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    cli_eval.add_arguments(parser)
    return cli_eval.run(parser.parse_args(argv))


def _video(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    cli_video.add_arguments(parser)
    return cli_video.run(parser.parse_args(argv))


def _flags(dataset: Path) -> list[str]:
    # random: FOUND a quarter of the time, so the videos show FOUND results too
    return [
        "--agent", "random", "--task", "1-on", "--dataset", str(dataset), "--in-process",
        "--max-steps", str(MAX_STEPS), "--image-size", "64", "--pictures", "0", "--quiet",
    ]  # fmt: skip


def _records(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def filmed_run(
    room_dataset: tuple[Path, list[Episode]], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    """A 3-episode run of the random agent, the first two filmed by ``--video 2`` (what the
    command printed is in ``printed.txt`` beside the run)."""
    out = tmp_path_factory.mktemp("video") / "run"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert _eval([*_flags(room_dataset[0]), "--out", str(out), "--video", "2"]) == 0
    (out.parent / "printed.txt").write_text(printed.getvalue())
    return out


def test_eval_counts_the_videos_in_the_files_it_wrote(filmed_run: Path) -> None:
    """Issue 53 item 5: "wrote 5 files" counted the report's files, not the two videos."""
    printed = (filmed_run.parent / "printed.txt").read_text().splitlines()
    report = sum(1 for path in filmed_run.rglob("*") if path.is_file() and path.suffix != ".mp4")
    assert (
        printed[-1]
        == f"wrote {report + 2} files to {filmed_run}: {report} of the report and 2 videos"
    )
    assert sum(1 for path in filmed_run.rglob("*") if path.is_file()) == report + 2
    assert [line.startswith(f"wrote {filmed_run / 'episode-'}") for line in printed[-3:-1]] == [
        True
    ] * 2


def test_eval_records_the_actions_and_films_the_first_episodes(filmed_run: Path) -> None:
    records = _records(filmed_run)
    assert len(records) == 3
    for record in records:
        assert set(record["actions"]) <= set("0123")
        assert len(record["actions"]) == record["metrics"]["steps"]
    videos = sorted(filmed_run.glob("*.mp4"))
    assert [v.name for v in videos] == [f"episode-{r['episode_id']}.mp4" for r in records[:2]]
    assert not list(filmed_run.glob(".*"))  # no temporary file left
    for video, record in zip(videos, records, strict=False):
        actions = record["actions"]
        expected = 1 + len(actions) + actions.count("0") * (FOUND_HOLD - 1) + END_HOLD
        frames = read_frames(video)
        assert len(frames) == expected
        height, width, _ = frames[0].shape
        assert height >= 256 and width % 2 == 0 and height % 2 == 0  # 64² camera, scaled up
        with av.open(str(video)) as container:
            stream = container.streams.video[0]
            assert stream.codec_context.name == "h264"
            assert stream.codec_context.pix_fmt == "yuv420p"
            assert float(stream.average_rate) == 10
        assert video.stat().st_size <= size_bound(expected)


def test_the_same_episode_gives_the_same_frames(filmed_run: Path, tmp_path: Path) -> None:
    episode_id = _records(filmed_run)[0]["episode_id"]
    again = tmp_path / "again.mp4"
    assert _video([str(filmed_run), "--episode", episode_id, "--out", str(again)]) == 0
    first, second = read_frames(filmed_run / f"episode-{episode_id}.mp4"), read_frames(again)
    assert len(first) == len(second)
    assert all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))
    # and frames differ from step to step: the video is not a still
    assert not np.array_equal(first[0], first[len(first) // 2])


def test_the_replayed_path_and_metrics_are_the_recorded_ones(
    room_dataset: tuple[Path, list[Episode]], tmp_path: Path
) -> None:
    path, episodes = room_dataset
    settings = EvalSettings(
        agent="random", num_goals=1, dataset=str(path), in_process=True, max_steps=MAX_STEPS
    )
    result = evaluate(settings, progress=False)
    from multion_agents.report.run_summary import write_report

    write_report(result, tmp_path, pictures=0)
    run = read_run(tmp_path)
    env = replay_env(run)
    try:
        for record, recorded, episode in zip(result.records, run.episodes, episodes, strict=True):
            views = list(replay(env, episode, recorded))
            walked = np.array([view.position for view in views])
            np.testing.assert_allclose(walked, record.path, atol=1e-9)
            assert views[-1].metrics == record.metrics
    finally:
        env.close()


def test_a_replay_that_does_not_reproduce_the_metrics_is_refused(
    filmed_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tampered = tmp_path / "tampered"
    shutil.copytree(filmed_run, tampered)
    records = _records(tampered)
    records[0]["metrics"]["path_length"] += 0.25
    lines = "".join(json.dumps(r) + "\n" for r in records)
    (tampered / "episodes.jsonl").write_text(lines)
    episode_id = records[0]["episode_id"]
    out = tampered / "out.mp4"
    assert _video([str(tampered), "--episode", episode_id, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "does not reproduce the recorded metrics" in error and "path_length" in error
    assert not out.exists() and not list(tampered.glob(".*"))  # nor a temporary file


def test_bad_video_requests_get_clear_errors(
    filmed_run: Path,
    room_dataset: tuple[Path, list[Episode]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    def error_of(code: int) -> str:
        assert code == 2
        return capsys.readouterr().err

    assert "no episode 'nope'" in error_of(_video([str(filmed_run), "--episode", "nope"]))
    (tmp_path / "empty").mkdir()
    message = error_of(_video([str(tmp_path / "empty"), "--episode", "x"]))
    assert "metrics.json does not exist" in message
    no_episodes = tmp_path / "no-episodes"
    no_episodes.mkdir()
    shutil.copy(filmed_run / "metrics.json", no_episodes)
    message = error_of(_video([str(no_episodes), "--episode", "x"]))
    assert "episodes.jsonl does not exist" in message

    flags = _flags(room_dataset[0])
    message = error_of(
        _eval([*flags, "--out", str(tmp_path / "e"), "--video", str(MAX_VIDEOS + 1)])
    )
    assert f"--video must be in [0, {MAX_VIDEOS}], got {MAX_VIDEOS + 1}" in message
    assert not (tmp_path / "e").exists()  # refused before the evaluation
    assert "--video needs --out" in error_of(_eval([*flags, "--video", "1"]))

    old = tmp_path / "old"  # a run written before actions were recorded
    shutil.copytree(filmed_run, old)
    records = _records(old)
    for record in records:
        del record["actions"]
    (old / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    message = error_of(_video([str(old), "--episode", records[0]["episode_id"]]))
    assert "no recorded actions" in message and "evaluate it again" in message

    long = tmp_path / "long"  # longer than the cap
    shutil.copytree(filmed_run, long)
    records[0]["actions"] = "2" * (MAX_VIDEO_FRAMES - END_HOLD)  # one frame too many
    (long / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    message = error_of(_video([str(long), "--episode", records[0]["episode_id"]]))
    assert f"{MAX_VIDEO_FRAMES + 1} frames" in message
    assert f"limited to {MAX_VIDEO_FRAMES} frames (10 minutes)" in message


def test_a_moved_dataset_is_named_and_can_be_given(
    filmed_run: Path,
    room_dataset: tuple[Path, list[Episode]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    moved = tmp_path / "moved"
    shutil.copytree(filmed_run, moved)
    metrics = json.loads((moved / "metrics.json").read_text())
    metrics["run"]["dataset"] = str(tmp_path / "gone.json.gz")
    (moved / "metrics.json").write_text(json.dumps(metrics))
    episode_id = _records(moved)[2]["episode_id"]
    assert _video([str(moved), "--episode", episode_id]) == 2
    assert "gone.json.gz is not here; give its file with --dataset" in capsys.readouterr().err
    # a --dataset that is not there is named as the given option (issue 53 item 5)
    assert _video([str(moved), "--episode", episode_id, "--dataset", str(tmp_path / "typo")]) == 2
    err = capsys.readouterr().err
    assert f"--dataset {tmp_path / 'typo'} does not exist: give the dataset file" in err
    assert "give its file with --dataset" not in err
    assert _video([str(moved), "--episode", episode_id, "--dataset", str(tmp_path)]) == 2
    assert f"--dataset {tmp_path} is a directory" in capsys.readouterr().err
    argv = [str(moved), "--episode", episode_id, "--dataset", str(room_dataset[0])]
    assert _video(argv) == 0
    assert (moved / f"episode-{episode_id}.mp4").is_file()
    assert "frames" in capsys.readouterr().out
    with pytest.raises(VideoError, match="not the dataset the run played"):
        other = tmp_path / "other.json.gz"
        other.write_bytes(room_dataset[0].read_bytes() + b"\0")
        from multion_agents.video.recorded import dataset_episode

        dataset_episode(read_run(moved, other), episode_id)


def test_a_still_is_the_frame_of_its_step(
    filmed_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from PIL import Image

    record = _records(filmed_run)[1]
    episode_id, actions = record["episode_id"], record["actions"]
    step = len(actions) // 2
    picture = tmp_path / "still.png"
    argv = [str(filmed_run), "--episode", episode_id, "--still", str(step)]
    assert _video([*argv, "--out", str(picture)]) == 0
    with Image.open(picture) as image:
        still = np.asarray(image.convert("RGB")).astype(np.int16)
    # the video's frame of that step (after the frames FOUNDs held before it), lossy-encoded
    index = step + actions[:step].count("0") * (FOUND_HOLD - 1)
    frame = read_frames(filmed_run / f"episode-{episode_id}.mp4")[index].astype(np.int16)
    assert still.shape == frame.shape
    assert np.abs(still - frame).mean() < 3  # H.264 at CRF 23: a few levels
    neighbour = read_frames(filmed_run / f"episode-{episode_id}.mp4")[index + FOUND_HOLD + 1]
    assert np.abs(still - neighbour.astype(np.int16)).mean() > np.abs(still - frame).mean()

    assert _video([*argv[:-1], str(len(actions) + 1), "--out", str(picture)]) == 2
    assert f"--still must be a step in [0, {len(actions)}]" in capsys.readouterr().err
    assert _video([*argv, "--out", str(tmp_path / "still.mp4")]) == 2
    assert "a --still is a PNG file" in capsys.readouterr().err


def test_two_filmers_of_one_episode_into_one_file_both_succeed(
    filmed_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two leaderboard replicas share a video folder and may film one episode at once (CI saw
    it: the first to finish moved a shared `.partial` file away under the other). Here a second
    film of the same episode starts and ends just before the first writes its trailer."""
    from multion.video import film as server_film
    from multion_agents.video.film import film_episode

    run = read_run(filmed_run)
    recorded = sorted(run.episodes, key=lambda e: e.index)[0]
    out = tmp_path / "episode.mp4"
    nested: list[int] = []
    started: list[bool] = []

    class InterruptedWriter(server_film.Mp4Writer):
        def close(self) -> None:  # the second film runs just before the first's trailer
            if not started:
                started.append(True)
                nested.append(film_episode(run, recorded, out).frames)
            super().close()

    monkeypatch.setattr(server_film, "Mp4Writer", InterruptedWriter)
    first = film_episode(run, recorded, out)
    assert nested == [first.frames]
    assert len(read_frames(out)) == first.frames
    assert [p.name for p in tmp_path.iterdir()] == ["episode.mp4"]  # no temporary left
