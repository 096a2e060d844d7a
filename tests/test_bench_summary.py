"""results/benchmarks.md is generated from pytest-benchmark's report: figures hand-checkable here."""
from tests.benchmarks.summary import first_sentences, render


def _bench(name, group, median, extra=None):
    return {"name": name, "group": group, "extra_info": extra or {},
            "stats": {"median": median, "iqr": median / 10, "min": median / 2, "rounds": 7}}


REPORT = {"datetime": "2026-11-30T18:00:00.000", "commit_info": {"id": "abcdef0123", "dirty": False},
          "machine_info": {"python_version": "3.11.9", "cpu": {"count": 2}},
          "benchmarks": [_bench("test_bench_fast", "g", 0.025, {"speedup_vs_baseline": 2.9, "peak_mib": 0.04}),
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
    assert fast[7] == "2.9x faster" and fast[8] == "peak_mib 0.04"
    assert rows["`test_bench_slow_baseline`"][6] == "baseline"
    assert rows["`test_bench_alone`"][2] == "2.5 s" and rows["`test_bench_alone`"][6] == ""   # no baseline
    assert "commit `abcdef0`" in md and "load average 0.20 before and 1.80 after" in md
    assert "| total | 982 | 42.5 | 82.5 | |" in md
    assert "-dirty" not in md and "-dirty" in render({**REPORT, "commit_info": {"id": "abc", "dirty": True}})


def test_the_fresh_clone_time_is_reported_when_measured():
    fresh = {"commit": "abcdef0", "wall_s": "57.3", "cpu_s": "101.2", "cpus": 2, "load_before": "0.05",
             "load_after": "1.90", "exit": 0}
    md = render(REPORT, fresh=fresh)
    assert "fresh clone of `abcdef0`" in md and "**57.3 s wall**, 101.2 CPU-s, exit 0" in md
    assert "fresh clone" not in render(REPORT)


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


def _scaled(report, factor=1.0, **medians):
    """``report`` with every median times ``factor`` (a slower or faster machine), then the named ones set."""
    out = [_bench(b["name"], b["group"], medians.get(b["name"], b["stats"]["median"] * factor))
           for b in report["benchmarks"]]
    return {**report, "commit_info": {"id": "0123456789"}, "benchmarks": out}


def test_a_machine_twice_as_slow_fails_nothing_a_lost_fast_path_fails():
    from tests.benchmarks.summary import gate

    slower = _scaled(REPORT, 2.0)                   # everything twice as slow: the ratios did not move
    lines, failed = gate(slower, {**REPORT, "commit_info": {"id": "0123456789"}}, factor=1.5)
    assert failed == []
    assert "| `test_bench_fast` | 25 ms | 50 ms | +100 % | 0.25 -> 0.25 (x1.00) |  |" in lines
    assert "no ratio to the same-run baseline grew by more than x1.5 over the stored run of commit `0123456` " \
           "(1 judged)" in lines[1]
    lost = _scaled(REPORT, test_bench_fast=0.05)    # the fast path twice as slow, its baseline unchanged
    lines, failed = gate(lost, REPORT, factor=1.5)
    assert failed == ["test_bench_fast"]
    assert "| `test_bench_fast` | 25 ms | 50 ms | +100 % | 0.25 -> 0.5 (x2.00) | **fails** |" in lines
    assert "1 of 1 ratios to the same-run baseline grew by more than x1.5" in lines[1]


def test_the_gate_takes_the_factor_as_stated_and_judges_only_ratios():
    from tests.benchmarks.summary import RATIO_FACTOR, gate

    noisy = _scaled(REPORT, 3.0, test_bench_fast=0.025 * 1.4 * 3.0)   # ratio x1.4 on a 3x slower machine
    assert gate(noisy, REPORT, factor=1.5)[1] == [] and gate(noisy, REPORT, factor=1.3)[1] == ["test_bench_fast"]
    lines = gate(noisy, REPORT)[0]
    alone = next(line for line in lines if "`test_bench_alone`" in line)       # 3x slower, no baseline: reported
    assert "+200 %" in alone and "no baseline" in alone and "fails" not in alone
    assert "| baseline |" in next(line for line in lines if "`test_bench_slow_baseline`" in line)
    assert RATIO_FACTOR == 2.0


def test_new_benchmarks_and_changed_baselines_are_reported_not_judged():
    from tests.benchmarks.summary import gate

    now = {**REPORT, "benchmarks": REPORT["benchmarks"] + [_bench("test_bench_new", "g", 0.5)]}
    then = {**REPORT, "benchmarks": [_bench("test_bench_fast", "g", 0.001), _bench("test_bench_alone", "h", 2.5)]}
    lines, failed = gate(now, then, factor=1.5)      # no baseline then: a 25x "slowdown" is not judged
    assert failed == []
    assert "| `test_bench_new` | - | 500 ms | new | 5 (none then) |  |" in lines
    assert "0.25 (none then)" in next(line for line in lines if "`test_bench_fast`" in line)


def test_the_summary_shows_the_gate_against_the_stored_run():
    md = render(_scaled(REPORT, test_bench_fast=0.05), reference=REPORT, factor=1.5)
    assert "1 of 1 ratios to the same-run baseline grew by more than x1.5 over the stored run of commit `abcdef0`" in md
    assert "Medians are reported, not judged" in md
    calm = render(REPORT, reference=REPORT)
    assert "no ratio to the same-run baseline grew by more than x2 over the stored run of commit `abcdef0` " \
           "(1 judged)" in calm


def test_make_bench_exits_1_on_a_grown_ratio_and_0_on_a_slower_machine(tmp_path, capsys):
    import json

    from tests.benchmarks.bench import judge

    ref, now = tmp_path / "0001_ref.json", tmp_path / "benchmarks.json"
    ref.write_text(json.dumps(REPORT))
    now.write_text(json.dumps(_scaled(REPORT, 2.5)))
    assert judge(now, ref) == 0
    now.write_text(json.dumps(_scaled(REPORT, test_bench_fast=0.09)))        # ratio 0.25 -> 0.9
    assert judge(now, ref) == 1 and "**fails**" in capsys.readouterr().out


def test_a_ratio_beyond_the_factor_fails_only_when_the_re_run_repeats_it():
    from tests.benchmarks.summary import confirmed, to_recheck

    first = _scaled(REPORT, test_bench_fast=0.09)                              # x3.6: flagged
    noise = {"benchmarks": [_bench("test_bench_fast", "g", 0.026), _bench("test_bench_slow_baseline", "g", 0.1)]}
    again = {"benchmarks": [_bench("test_bench_fast", "g", 0.08), _bench("test_bench_slow_baseline", "g", 0.1)]}
    assert confirmed(first, noise, REPORT, factor=2) == []
    assert confirmed(first, again, REPORT, factor=2) == ["test_bench_fast"]
    assert confirmed(REPORT, again, REPORT, factor=2) == []                   # not flagged the first time
    withids = {"benchmarks": [{**b, "fullname": f"tests/benchmarks/t.py::{b['name']}"} for b in REPORT["benchmarks"]]}
    assert to_recheck(withids, ["test_bench_fast"]) == ["tests/benchmarks/t.py::test_bench_fast",
                                                       "tests/benchmarks/t.py::test_bench_slow_baseline"]


def test_versus_medians_and_ratios_by_hand():
    """The before/after table of tests/benchmarks/versus.py: medians of the successful runs per command and
    pair of commits, a failed run counted and left out of the medians."""
    from tests.benchmarks import versus

    def row(label, wall, cpu, code=0, versus_="a1..b2", command="make reproduce"):
        return {"versus": versus_, "label": label, "commit": {"before": "a1", "after": "b2"}[label],
                "command": command, "wall_s": str(wall), "cpu_s": str(cpu), "exit": str(code)}
    rows = [row("before", 50, 90), row("after", 60, 99), row("before", 52, 94), row("after", 55, 100),
            row("before", 51, 92), row("after", 999, 999, code=1)]
    (m,) = versus.medians(rows)
    assert (m["n"], m["wall"], m["wall_after"], m["cpu"], m["cpu_after"], m["failed"]) == (2, 51, 57.5, 92, 99.5, 1)
    text = versus.render(rows + [row("before", 1, 1, versus_="c3..d4", command="make test")])
    assert "| make reproduce | `a1` | `b2` | 2 | 51.0 | 57.5 | 1.13 | 92.0 | 99.5 | 1.08 | 1 |" in text
    assert "| make test | | | 0 |" in text                   # no successful 'after' run: no times, no ratio
