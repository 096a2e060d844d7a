"""Several studies in one command (``jointbench run A B --jobs N``, make reproduce): forked children after
the shared imports, at most N at once, each study's numbers those of a run of its own, the exit status the
worst child's, signals passed on once (issue 22)."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest

from jointbench.benchmarks.harness.side_by_side import exit_code, run_forked
from tests.harness_studies import alive, cache_entries, children, cli_env, cli_here, start, tiny_study, wait_for

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses fork, /proc and POSIX signals")


def test_run_forked_keeps_to_jobs_at_once_and_returns_each_childs_status(tmp_path):
    """Six children, two at once: no more than two ever overlap (their own start and end stamps), and the
    statuses come back in the order of the items: a returned status, SystemExit's, 1 for an escaped
    exception, 128 + 9 for a child killed by SIGKILL."""
    def one(i):
        (tmp_path / f"{i}.start").write_text(repr(time.monotonic()))
        time.sleep(0.3)
        # and until the next item has started (at most 3 s): with two at once it starts while this one runs,
        # however late a loaded machine starts it (with 0.3 s alone the side-by-side check below failed now and
        # then); one at a time, this one ends first and that check fails
        nxt, t_end = tmp_path / f"{i + 1}.start", time.monotonic() + 3
        while i < 5 and not nxt.exists() and time.monotonic() < t_end:
            time.sleep(0.01)
        (tmp_path / f"{i}.end").write_text(repr(time.monotonic()))
        if i == 3:
            raise SystemExit(3)
        if i == 4:
            raise RuntimeError("escaped")
        if i == 5:
            os.kill(os.getpid(), signal.SIGKILL)
        return 7 if i == 1 else 0

    codes = run_forked(list(range(6)), 2, one)
    assert codes == [0, 7, 0, 3, 1, 137]
    spans = [(float((tmp_path / f"{i}.start").read_text()), float((tmp_path / f"{i}.end").read_text()))
             for i in range(6)]
    running = [sum(a <= t < b for a, b in spans) for t, _ in spans]     # children running at each start
    # no more than two, and two did run side by side (at whichever start came second: on a loaded machine the
    # second child can stamp its start before the first does)
    assert max(running) == 2, spans
    with pytest.raises(ValueError, match="jobs must be >= 1"):
        run_forked([1], 0, one)


def test_exit_code_is_the_shells():
    assert exit_code(0) == 0 and exit_code(2 << 8) == 2 and exit_code(signal.SIGTERM) == 128 + signal.SIGTERM


def _values(folder: Path) -> pd.DataFrame:
    rows = pd.read_parquet(folder / "cases.parquet")
    keep = [c for c in rows.columns if c not in ("wall_time_s", "git_commit", "sim_time_s")]
    return rows[keep].sort_values(["case_id", "metric", "estimator"]).reset_index(drop=True)


@pytest.fixture(scope="module")
def side_by_side(tmp_path_factory):
    """``run tiny_a tiny_b --jobs 2 --serial --quiet --write-readme`` from a folder with a stale README: the
    command of make reproduce, once for the two tests below (a command with --jobs pays 5 CPU-s of
    start-up and imports before its studies). What they read of the results folder and the
    README is taken at once, before either test runs anything else there."""
    from jointbench.benchmarks import status

    folder = tmp_path_factory.mktemp("side_by_side")
    a = tiny_study(folder / "configs", study="tiny_a", seeds=3, duration="8 s")
    b = tiny_study(folder / "configs", study="tiny_b", seeds=2, duration="6 s")
    readme = folder / "README.md"
    readme.write_text(f"# x\n{status.BEGIN}\nstale\n{status.END}\ntail\n")
    out = folder / "both"
    r = subprocess.run([sys.executable, "-m", "jointbench", "run", str(a), str(b), "--jobs", "2",
                        "--serial", "--quiet", "--write-readme", "--out", str(out)],
                       cwd=folder, capture_output=True, text=True, timeout=300, env=cli_env())
    return SimpleNamespace(a=a, b=b, out=out, readme=readme, r=r, block=status.block(out) if out.is_dir() else None,
                           readme_text=readme.read_text())


def test_studies_side_by_side_give_the_numbers_of_runs_of_their_own(side_by_side, tmp_path):
    """Two studies with --jobs 2: each summary printed whole, each study's rows those of a run of its own
    (the children share the parent's imports, nothing else), exit 0; --parts with two studies is refused."""
    a, b, r = side_by_side.a, side_by_side.b, side_by_side.r
    assert r.returncode == 0, r.stdout + r.stderr
    for study, n in (("tiny_a", 3), ("tiny_b", 2)):
        block = re.search(rf"^{study}: {n} cases \(0 from cache, {n} computed\).*?\n((?:  .*\n)+)"
                          rf"wrote .*{study}/report.md", r.stdout, re.M)
        assert block and len(block.group(1).splitlines()) == 2, r.stdout      # its two checks, not interleaved
    alone = cli_here("run", a, "--serial", "--quiet", "--out", tmp_path / "alone")
    assert alone.returncode == 0, alone.stderr
    pd.testing.assert_frame_equal(_values(side_by_side.out / "tiny_a"), _values(tmp_path / "alone" / "tiny_a"))
    refused = cli_here("run", a, b, "--parts", "fit", "--out", tmp_path / "x")
    assert refused.returncode == 2 and "--parts fit names parts of one study" in refused.stderr
    refused = cli_here("run", a, b, "--set", "fit.seeds=1", "--out", tmp_path / "x")
    assert refused.returncode == 2 and "--set fit.seeds=1 names parts of one study" in refused.stderr
    every = cli_here("run", a, b, "--set", "*.seeds=1", "--serial", "--quiet", "--out", tmp_path / "x")
    assert every.returncode == 0 and every.stdout.count(": 1 cases (") == 2, every.stdout + every.stderr
    again = cli_here("run", a, b, "--serial", "--quiet", "--out", side_by_side.out)   # --jobs 1: in turn
    assert again.returncode == 0 and again.stdout.count("from cache, 0 computed") == 2, again.stdout


def test_write_readme_rewrites_the_status_block_after_the_studies(side_by_side, tmp_path, monkeypatch):
    """``--write-readme`` (make reproduce): once the studies end well the command rewrites the status block
    of ./README.md from the results folder, as ``jointbench status --write-readme`` would."""
    from jointbench.benchmarks import status

    a, b, r, readme = side_by_side.a, side_by_side.b, side_by_side.r, side_by_side.readme
    assert r.returncode == 0 and f"{readme}: status block rewritten" in r.stdout, r.stdout + r.stderr
    assert status.readme_block(readme) == side_by_side.block and "tiny_b" in side_by_side.readme_text
    # where there is no README (an installed wheel's user): one line before any case runs, for run and status.
    # In this process, from that folder (no interpreter of their own): the refusal comes before any study is
    # forked
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    for args in (["run", str(a), str(b), "--jobs", "2", "--write-readme", "--out", str(elsewhere / "out")],
                 ["status", "--write-readme", "--results", str(side_by_side.out)]):
        r = cli_here(*args)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert "README.md: No such file or directory: --write-readme rewrites" in r.stderr, r.stderr
    assert not (elsewhere / "out").exists()


@pytest.mark.parametrize("how", ["SIGINT to the process group (Ctrl-C)", "SIGTERM to the command"])
def test_a_signal_to_the_command_stops_every_study_keeping_their_finished_cases(tmp_path, how):
    """Ctrl-C (the command's process group) or SIGTERM (the command) while two studies run: the command
    passes it on once, each child stops as a run of its own does (its finished cases kept, its line on
    stderr), no child outlives the command, exit 130 or 143."""
    # records of 120 s and 119 s: cases of their own (a cache key has no study name), so that the wait below
    # sees each study's finished cases
    studies = [tiny_study(tmp_path / "configs", study=f"slow_{k}", seeds=40, duration=d)
               for k, d in (("a", "120 s"), ("b", "119 s"))]
    out = tmp_path / "out"
    p = start("run", *studies, "--jobs", "2", "--serial", "--quiet", "--out", out, log=tmp_path / "run.log")
    assert wait_for(lambda: len(children(p.pid)) == 2 or p.poll() is not None, 300), "no children"
    kids = children(p.pid)

    def studies_at_work() -> set[str]:
        """The studies with a finished case in the cache (each entry names the study that wrote it)."""
        seen = set()
        for entry in cache_entries(out):
            try:
                seen.add(json.loads(entry.read_text())["study"])
            except (OSError, ValueError, KeyError):
                pass
        return seen

    # the signal comes once both studies are running their cases (two entries could be one study's, while the
    # other was still setting up: it then said "interrupted" without its count, and the test failed)
    assert wait_for(lambda: studies_at_work() == {"slow_a", "slow_b"} or p.poll() is not None, 300) and \
        p.poll() is None, (tmp_path / "run.log").read_text()
    if how.startswith("SIGINT"):
        os.killpg(p.pid, signal.SIGINT)
    else:
        os.kill(p.pid, signal.SIGTERM)
    p.wait(60)
    log = (tmp_path / "run.log").read_text()
    word, code = ("interrupted", 130) if how.startswith("SIGINT") else ("terminated", 143)
    assert p.returncode == code, log
    assert len(re.findall(rf"{word}: \d+ of 40 cases finished and kept", log)) == 2, log
    assert wait_for(lambda: not any(alive(k) for k in kids), 5)


def test_studies_never_started_after_an_interrupt_are_not_reported_as_success(tmp_path):
    """Ctrl-C while the first of three items runs one at a time: the running child is stopped, the two never
    started get 130 (128 + SIGINT), so the command cannot exit 0."""
    script = tmp_path / "forked.py"
    script.write_text(textwrap.dedent('''
        import os, signal, sys, time
        from jointbench.benchmarks.harness.side_by_side import run_forked

        def one(i):
            try:
                os.kill(os.getppid(), signal.SIGINT)     # the command is interrupted while item 0 runs
                time.sleep(30)
                return 0
            except KeyboardInterrupt:
                return 130

        print(run_forked([0, 1, 2], 1, one))
    '''))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60,
                       start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert r.returncode == 0 and r.stdout.strip() == "[130, 130, 130]", r.stdout + r.stderr
