"""``multion bench --only sim`` runs end to end (its numbers are measured, not asserted: the
machines are shared and noisy; here only that every part runs and reports a rate)."""

from multion.bench import bench_sim


def test_the_simulator_bench_runs_every_part(capsys):
    results = bench_sim(steps=3, episodes=1)
    out = capsys.readouterr().out
    # the appearance comparison (textured vs plain scene) once crashed on a renderer argument
    assert "textures and lighting" in out
    for key in ("env_sps_tiny_256", "raw_sps_tiny_256", "plain_rps_256", "textured_rps_256"):
        assert results[key] > 0, key
    assert results["generate_s"] > 0
