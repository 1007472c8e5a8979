"""``multion bench`` parts run end to end (its numbers are measured, not asserted: the
machines are shared and noisy; here only that every part runs and reports a rate)."""

import pytest

from multion_agents.bench.cli import bench_sim
from multion_agents.bench.reset import run_reset_bench
from multion_agents.bench.site_diversity import room_pair_homogeneity, run_diversity_bench


def test_the_simulator_bench_runs_every_part(capsys):
    results = bench_sim(steps=3, episodes=1)
    out = capsys.readouterr().out
    # the appearance comparison (textured vs plain scene) once crashed on a renderer argument
    assert "textures and lighting" in out
    for key in ("env_sps_tiny_256", "raw_sps_tiny_256", "plain_rps_256", "textured_rps_256"):
        assert results[key] > 0, key
    assert results["generate_s"] > 0
    # the house's draws per image are printed: a body per box with TinyRenderer, a few with EGL
    assert results["draws_tiny"] > 400 and "scene draws per image" in out
    if "env_sps_egl_256" in results:
        assert results["draws_egl_per_box"] == results["draws_tiny"]
        assert results["draws_egl"] == results["draws_egl_merged"] <= 3
        assert results["rps_egl_merged_far_light_256"] > 0


def test_the_lanes_bench_plays_a_run_with_one_lane_and_with_three() -> None:
    from multion_agents.bench.lanes import run_lanes_bench

    figures = run_lanes_bench(size=16, episodes=4, max_steps=5, rooms=1, verbose=False, lanes=3)
    assert figures["steps"] == 4 * 5  # every episode to its step limit, nothing lost
    assert figures["one_lane_s"] > 0 and figures["lanes_s"] > 0 and figures["ratio"] > 0
    hours = figures["full_run_hours"]  # 2.5M steps at each measured rate
    assert hours[1] == pytest.approx(2_500_000 * figures["one_lane_s"] / 20 / 3600)
    assert set(hours) == {1, 3}
    with pytest.raises(ValueError, match="lanes must be in"):
        run_lanes_bench(lanes=9)


def test_the_participants_bench_plays_every_run_to_its_end() -> None:
    from multion_agents.bench.participants import run_participants_bench

    figures = run_participants_bench(
        participants=3, size=16, episodes=2, max_steps=5, rooms=1, verbose=False
    )
    assert figures["steps"] == 3 * 2 * 5  # every participant's episodes, nothing lost
    assert figures["steps_per_s"] > 0
    assert 0 < figures["latency_p50_ms"] <= figures["latency_p90_ms"] <= figures["latency_p99_ms"]


def test_the_reset_bench_times_both_samplers_and_splits_out_the_fast_marching(capsys):
    results = run_reset_bench(resets=3, tasks=(1,), warm=False, plain=26)
    # the plain env: 25 episodes per house, so the 26 resets after the first switch house once
    assert results["1on_plain_switches"] == 1
    assert 0 < results["1on_plain_same_house_median_ms"] < results["1on_plain_switch_median_ms"]
    assert results["1on_plain_mean_ms"] >= results["1on_plain_same_house_median_ms"] * 0.5
    # online: the start's field and the goal's every time; sites: at most the goal's
    assert results["1on_online_fields_median"] >= 2
    assert results["1on_sites_fields_median"] <= 1
    for sampler in ("online", "sites"):
        median = results[f"1on_{sampler}_median_ms"]
        assert 0 <= results[f"1on_{sampler}_marching_median_ms"] < median * 1.0001
        assert results[f"1on_{sampler}_rest_median_ms"] > 0
    assert "fast marching" in capsys.readouterr().out


def test_the_diversity_bench_compares_each_sampler_with_the_online_one(capsys):
    results = run_diversity_bench(houses=1, episodes_per_house=4, site_counts=(16,))
    assert results["online_ks_d"] == 0.0 and results["online_room_pairs_tvd"] == 0.0
    assert results["online-again_ks_d"] > 0.0  # another seed: other legs
    assert results["sites-16_goal_cells_per_house"] <= 16
    assert 0.0 < results["sites-16_room_pairs_tvd"] <= 1.0
    assert "sites-16" in capsys.readouterr().out


def test_room_pairroom_pair_homogeneity_is_zero_for_one_sample_and_one_for_disjoint_ones():
    same = ["kitchen → bedroom"] * 30 + ["bedroom → bedroom"] * 20
    assert (
        room_pair_homogeneity(same, same)[0] == 0.0 and room_pair_homogeneity(same, same)[3] == 0.0
    )
    other = ["hall → hall"] * 50
    chi2, dof, p_value, tvd = room_pair_homogeneity(same, other)
    assert tvd == 1.0 and p_value < 1e-6 and dof >= 1
