"""``multion bench --only sim``'s gl part runs end to end: gl beside TinyRenderer at every size,
and its pictures against TinyRenderer's (the speed figures are measured, not asserted: the
machine is shared; docs/rendering.md has them)."""

from __future__ import annotations

import pytest

from multion_agents.bench.gl import SIZES, bench_gl_pictures, bench_gl_speed


@pytest.mark.slow
def test_the_gl_bench_times_both_renderers_and_compares_their_pictures(
    gl: None, capsys: pytest.CaptureFixture[str]
) -> None:
    speed = bench_gl_speed(steps=3)
    for size in SIZES:
        for renderer in ("tiny", "gl"):
            assert speed[f"gl_bench_env_sps_{renderer}_{size}"] > 0
        assert speed[f"gl_speedup_{size}"] > 0
    pictures = bench_gl_pictures(poses_per_house=2, houses=1)
    for size in SIZES:
        assert pictures[f"gl_pictures_depth_{size}"] >= 0.99
        assert pictures[f"gl_pictures_segmentation_{size}"] >= 0.99
    printed = capsys.readouterr().out
    assert "gl / tiny: env steps" in printed and "images: depth" in printed
