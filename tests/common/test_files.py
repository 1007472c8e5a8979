"""Atomic writes (multion.common.files) and the files written through them."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest

from multion.common.files import replacing, write_atomically
from multion.config.datasets import load_dataset, packaged_dataset_path, read_header, save_dataset


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "results.csv"
    write_atomically(target, "old\n")
    with pytest.raises(RuntimeError, match="disk full"), replacing(target) as temporary:
        temporary.write_text("half a fi")
        raise RuntimeError("disk full")
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv"]


def test_written_files_are_readable_by_others_and_keep_their_bytes(tmp_path: Path) -> None:
    write_atomically(tmp_path / "a.txt", "line\r\n")
    write_atomically(tmp_path / "b.bin", b"\x00\xff")
    assert (tmp_path / "a.txt").read_bytes() == b"line\r\n"  # no newline translation
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\xff"
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o644


def test_the_temporary_keeps_the_suffix_that_writers_read(tmp_path: Path) -> None:
    with replacing(tmp_path / "atlas.png") as temporary:
        assert temporary.suffix == ".png" and temporary.parent == tmp_path
        temporary.write_bytes(b"png")


@pytest.mark.parametrize("task", [1, 3])
def test_saving_a_packaged_dataset_again_gives_the_same_bytes(tmp_path: Path, task: int) -> None:
    """The gzip header holds no file name and no time, so a dataset's bytes (and its digest)
    depend on its episodes alone."""
    packaged = packaged_dataset_path(task, "val")
    header = read_header(packaged)
    again = save_dataset(tmp_path / "val.json.gz", load_dataset(packaged), task, "val",
                         header.get("generator"))  # fmt: skip
    assert again.read_bytes() == packaged.read_bytes()
