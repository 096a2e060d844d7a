"""results/benchmarks.md is generated from pytest-benchmark's report: figures hand-checkable here."""
from tests.benchmarks.summary import first_sentences, render


def _bench(name, group, median, extra=None):
    return {"name": name, "group": group, "extra_info": extra or {},
            "stats": {"median": median, "iqr": median / 10, "min": median / 2, "rounds": 7}}


REPORT = {"datetime": "2026-11-30T18:00:00.000", "commit_info": {"id": "abcdef0123", "dirty": False},
          "machine_info": {"python_version": "3.11.9", "cpu": {"count": 2}},
          "benchmarks": [_bench("test_bench_fast", "g", 0.025, {"speedup_vs_baseline": 2.9, "target_s": 0.04}),
                         _bench("test_bench_slow_baseline", "g", 0.1),
                         _bench("test_bench_alone", "h", 2.5)]}


def test_ratio_to_the_groups_baseline_and_the_recorded_figures():
    md = render(REPORT, [{"study": "xu1998", "cases": "950", "wall_s": "40.0", "cpu_s": "78.5",
                          "load_before": "0.1", "load_after": "1.9"},
                         {"study": "westwick2012", "cases": "32", "wall_s": "2.5", "cpu_s": "4.0",
                          "load_before": "1.9", "load_after": "1.7"}], ("0.20", "1.80"))
    rows = {line.split("|")[2].strip(): [c.strip() for c in line.split("|")[1:-1]]
            for line in md.splitlines() if line.startswith("| g ") or line.startswith("| h ")}
    fast = rows["`test_bench_fast`"]
    assert fast[2:7] == ["25 ms", "2.5 ms", "12.5 ms", "7", "0.25"]          # 0.025 / 0.1
    assert fast[7] == "2.9x faster" and fast[8] == "target_s 0.04"
    assert rows["`test_bench_slow_baseline`"][6] == "baseline"
    assert rows["`test_bench_alone`"][2] == "2.5 s" and rows["`test_bench_alone`"][6] == ""   # no baseline
    assert "commit `abcdef0`" in md and "load average 0.20 before and 1.80 after" in md
    assert "| total | 982 | 42.5 | 82.5 | |" in md
    assert "-dirty" not in md and "-dirty" in render({**REPORT, "commit_info": {"id": "abc", "dirty": True}})


def test_every_benchmark_module_parses():
    names = first_sentences()
    assert "test_bench_fsewls_45s" in names and "test_bench_sds" in names


def test_with_two_baselines_each_benchmark_takes_the_one_named_like_it():
    report = {**REPORT, "benchmarks": [_bench("test_bench_mujoco_backend", "m", 0.2),
                                       _bench("test_bench_analytic_backend_baseline", "m", 0.01),
                                       _bench("test_bench_mujoco_whole_trial", "m", 0.3),
                                       _bench("test_bench_analytic_whole_trial_baseline", "m", 0.02)]}
    rows = {line.split("|")[2].split(":")[0].strip(): line.split("|")[7].strip()     # label: name[: docstring]
            for line in render(report).splitlines() if line.startswith("| m ")}
    assert rows["`test_bench_mujoco_backend`"] == "20" and rows["`test_bench_mujoco_whole_trial`"] == "15"
    assert rows["`test_bench_analytic_backend_baseline`"] == "baseline"


def test_the_comparison_with_the_stored_run_names_what_is_beyond_the_limit():
    reference = {**REPORT, "commit_info": {"id": "0123456789"},
                 "benchmarks": [_bench("test_bench_fast", "g", 0.020), _bench("test_bench_slow_baseline", "g", 0.1),
                                _bench("test_bench_alone", "h", 2.5)]}
    md = render(REPORT, reference=reference, limit=20)
    assert "1 of 3 medians more than 20 % slower than the stored run of commit `0123456`" in md
    assert "| `test_bench_fast` | 20 ms | 25 ms | +25 % | **slower** |" in md        # 0.025 / 0.020
    assert "| `test_bench_slow_baseline` | 100 ms | 100 ms | +0 % |  |" in md
    calm = render(REPORT, reference=REPORT)
    assert "no median more than 20 % slower than the stored run of commit `abcdef0` (3 compared)" in calm
