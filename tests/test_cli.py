"""The ``multion`` command line: pictures, dataset checks and help, run as a user would."""

import gzip

from PIL import Image

from multion_agents.cli import main


def test_scene_picture_writes_a_png(tmp_path, capsys):
    out = tmp_path / "room.png"
    assert main(["scene", "picture", "room-6x4", "--out", str(out)]) == 0
    image = Image.open(out)
    assert image.format == "PNG" and image.width > 100
    # agent centres on x∈[0.1, 5.9], y∈[0.1, 3.9]: 117 × 77 cells of 0.05 m
    assert "22.5 m² navigable" in capsys.readouterr().out


def test_scene_picture_bad_id(tmp_path, capsys):
    assert main(["scene", "picture", "castle-1", "--out", str(tmp_path / "x.png")]) == 2
    assert "castle-1" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_dataset_check_reports_corrupt_file(tmp_path, capsys):
    bad = tmp_path / "bad.json.gz"
    with gzip.open(bad, "wt") as handle:
        handle.write(
            '{"format": "multion-episodes", "version": 3, "episodes": [{"episode_id": 1}]}'
        )
    assert main(["dataset", "check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "bad.json.gz" in err and "missing field" in err


def test_help_lists_commands(capsys):
    assert main([]) == 2
    out = capsys.readouterr().out
    for command in ("serve", "eval", "dataset", "scene", "bench"):
        assert command in out
