"""``multion bench --only site-memory`` runs end to end, and its envs march each site once."""

from multion_agents.bench.site_memory import run_site_memory_bench


def test_the_site_memory_bench_marches_each_site_once_for_all_its_envs(capsys):
    figures = run_site_memory_bench(envs=2, houses=2, limit_gib=4)
    # 2 houses × 32 sites; per-env caches marched them once per env (about 2 × 64)
    assert 0 < figures["warm_marched"] <= 2 * 32
    assert figures["imported_mib"] < figures["open_mib"] <= figures["peak_mib"]
    assert "every site of 2 train houses cached" in capsys.readouterr().out
