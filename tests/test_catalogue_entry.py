"""Issue 33's bad-input catalogue, causes 2, 4, 5 and 7, each fed to the code where it enters: registered names
are owned (a plugin cannot take a built-in's name, whatever the import order); every public function of
jointbench.api checks its arguments where they enter, with the rules the command line's types use; the HTML
pages neither let a hostile name end their embedded JSON nor render a ``javascript:`` link; configuration
that would have no effect, or leave nothing to run, is refused with the reason."""
from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jointbench import api, estimators
from jointbench.core import arguments, plugins
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.registry import Registration, Registry
from jointbench.core.types import Trial
from tests.test_nightly import _browser, chromium  # noqa: F401  (the project's Chromium fixture)

REPO = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------- 2. names are owned
def _plugin(tmp_path: Path, module: str, body: str) -> Path:
    path = tmp_path / f"{module}.py"
    path.write_text(textwrap.dedent(body))
    return path


def _forget(*names: str) -> None:
    for name in names:
        estimators.REGISTRY._items.pop(name, None)
        estimators.REGISTRY._tags.pop(name, None)


CLASH = """
    from jointbench.estimators import Estimator, register

    @register({name!r})
    class Impostor(Estimator):
        '''Takes a built-in's name.'''

        def _fit(self, trials):
            return 12345.0
    """


@pytest.mark.parametrize("name", ["irf2_ls", "fsewls"])
def test_a_plugin_cannot_take_a_builtin_estimator_name_after_it_is_imported(tmp_path, name):
    builtin = estimators.REGISTRY.get(name)                  # the built-in's module imported first
    path = _plugin(tmp_path, f"clash_after_{name}", CLASH.format(name=name))
    with pytest.raises(ConfigError) as exc:
        plugins.load(str(path))
    msg = str(exc.value)
    assert "\n" not in msg and f"clash_after_{name}" in msg and "jointbench.estimators." in msg, msg
    assert "built-in" in msg
    assert estimators.REGISTRY.get(name) is builtin


@pytest.mark.parametrize("name", ["irf2_ls", "fsewls"])
def test_a_plugin_imported_before_the_builtin_cannot_take_its_name(tmp_path, name):
    """The other order, in a fresh process: the plugin is imported before the built-in's module (deferred),
    and the command's ``--list`` and ``-e`` agree on the built-in."""
    path = _plugin(tmp_path, f"clash_before_{name}", CLASH.format(name=name))
    code = textwrap.dedent(f"""
        import sys
        from jointbench import estimators
        from jointbench.core import plugins
        from jointbench.core.errors import ConfigError
        assert estimators.REGISTRY.module_of({name!r}) not in sys.modules
        try:
            plugins.load({str(path)!r})
        except ConfigError as exc:
            print("ERROR", exc)
        print("MODULE", estimators.REGISTRY.get({name!r}).__module__)
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 0, r.stderr
    assert f"ERROR --plugin: plugin '{path}': estimator '{name}' of clash_before_{name} clashes with the " \
           f"built-in" in r.stdout, r.stdout
    assert "MODULE jointbench.estimators." in r.stdout and "clash_before" not in r.stdout.split("MODULE")[1]


def test_the_command_line_refuses_a_plugin_that_takes_a_builtin_name(tmp_path):
    path = _plugin(tmp_path, "clash_cli", CLASH.format(name="fsewls"))
    r = subprocess.run([sys.executable, "-m", "jointbench", "estimate", "--plugin", str(path), "--list"],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "clash_cli" in r.stderr and "jointbench.estimators.fsewls" in r.stderr


def test_two_plugins_with_one_name_is_an_error_naming_both(tmp_path):
    body = CLASH.format(name="twin_method_i33")
    first, second = _plugin(tmp_path, "twin_one", body), _plugin(tmp_path, "twin_two", body)
    try:
        plugins.load(str(first))
        with pytest.raises(ConfigError, match=r"estimator 'twin_method_i33' is registered by both twin_one and "
                                              r"twin_two; rename one of them$"):
            plugins.load(str(second))
        assert estimators.REGISTRY.get("twin_method_i33").__module__ == "twin_one"
    finally:
        _forget("twin_method_i33")


@pytest.mark.parametrize("name", ["", " ", "1st", "a b", "x/y", "name\n", "..", None, 3])
def test_a_name_must_be_a_name(name):
    reg = Registry("thing")
    with pytest.raises(ConfigError, match=r"thing name .* is not a name"):
        reg.register(name)(object())
    with pytest.raises(ConfigError, match=r"thing name .* is not a name"):
        reg.defer([Registration(name, "some.module", frozenset(), "")])
    assert reg.names() == []


def test_valid_names_and_the_owner_registering_again():
    reg = Registry("thing")
    for name in ("irf2_ls", "xu1998.track", "a-b", "_x9"):
        reg.register(name, module="pkg.mod")(object())
    reg.register("irf2_ls", module="pkg.mod")(object())     # its module imported again: its own entry replaced
    assert reg.names() == ["_x9", "a-b", "irf2_ls", "xu1998.track"]


def test_every_registry_owns_its_names():
    """The simulator's registries share the class: a plugin's joint model cannot replace a built-in one."""
    from jointbench import sims

    builtin = sims.JOINTS.get("second_order")
    with pytest.raises(ConfigError, match=r"joint model 'second_order' of my_joints clashes with the built-in "
                                          r"joint model 'second_order' \(jointbench\.sims\.joint_second_order\)"):
        sims.JOINTS.register("second_order", module="my_joints")(object)
    assert sims.JOINTS.get("second_order") is builtin
    for reg in (sims.PERTURBATIONS, sims.PROFILES, sims.BACKENDS, sims.REFLEXES):
        name = reg.names()[0]
        with pytest.raises(ConfigError, match="clashes with the built-in"):
            reg.register(name, module="someone_else")(object)


def test_no_registered_name_is_empty_or_odd():
    from jointbench import sims
    from jointbench.benchmarks import figures, protocols

    for reg in (estimators.REGISTRY, sims.JOINTS, sims.PERTURBATIONS, sims.PROFILES, sims.BACKENDS, sims.REFLEXES,
                protocols.REGISTRY, figures.REGISTRY):
        assert reg.names() and all(re.fullmatch(r"[A-Za-z_][\w.-]*", n) for n in reg.names()), reg.kind


# ------------------------------------------------------------------------ 4. the API checks its arguments
@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(7)
    angle = rng.standard_normal(1000) * 0.01
    torque = 50 * angle + 0.001 * rng.standard_normal(1000)
    return angle, torque


def _calls(angle, torque, history: Path):
    """(public function, call, argument the message must name): wrong types and values for every argument of
    every public function of jointbench.api."""
    fit = dict(angle=angle, torque=torque, fs=100)
    h = api.History(history)
    return [
        ("estimators", None, None),                      # no arguments
        ("scenarios", None, None),
        ("settings", lambda: api.settings(5), "estimator"),
        ("settings", lambda: api.settings(""), "estimator"),
        ("load_plugin", lambda: api.load_plugin(5), "ref"),
        ("load_plugin", lambda: api.load_plugin(None), "ref"),
        ("read", lambda: api.read(5), "path"),
        ("read", lambda: api.read("x.csv", fs=0), "fs"),
        ("read", lambda: api.read("x.csv", fs=float("nan")), "fs"),
        ("read", lambda: api.read("x.csv", fs="fast"), "fs"),
        ("read", lambda: api.read("x.csv", array=3), "array"),
        ("read", lambda: api.read("x.csv", schedule=["a"]), "schedule"),
        ("fit", lambda: api.fit(5, **fit), "estimator"),
        ("fit", lambda: api.fit("irf2_ls", angle=angle, torque=torque, fs=0), "fs"),
        ("fit", lambda: api.fit("irf2_ls", angle=angle, torque=torque, fs=float("nan")), "fs"),
        ("fit", lambda: api.fit("irf2_ls", angle=angle, torque=torque, fs="100 s"), "fs"),
        ("fit", lambda: api.fit("irf2_ls", angle=angle, torque=torque, fs=True), "fs"),
        ("fit", lambda: api.fit("irf2_ls", **fit, settings="lag_before=40ms"), "settings"),
        ("fit", lambda: api.fit("irf2_ls", **fit, settings=["lag_before=40ms"]), "settings"),
        ("fit", lambda: api.fit("irf2_ls", **fit, decimate="2"), "decimate"),
        ("fit", lambda: api.fit("irf2_ls", **fit, decimate=2.0), "decimate"),
        ("fit", lambda: api.fit("irf2_ls", **fit, decimate=0), "decimate"),
        ("fit", lambda: api.fit("irf2_ls", **fit, decimate=10**30), "decimate"),
        ("fit", lambda: api.fit("irf2_ls", **fit, window=5), "window"),
        ("fit", lambda: api.fit("irf2_ls", **fit, torque_sign=2), "torque_sign"),
        ("fit", lambda: api.fit("irf2_ls", **fit, ensemble="yes"), "ensemble"),
        ("fit", lambda: api.fit("irf2_ls", **fit, schedule=5), "schedule"),
        ("fit", lambda: api.fit("irf2_ls", "x.npz", array=5), "array"),
        ("fit", lambda: api.fit("irf2_ls", data=5), "data"),
        ("score", lambda: api.score(5, None), "estimate"),
        ("joint", lambda: api.joint(5), "name"),
        ("scenario", lambda: api.scenario(5), "name"),
        ("experiment", lambda: api.experiment(5), "config"),
        ("experiment", lambda: api.experiment("matrix:xu1998_elbow", backend=3), "backend"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", seed="x"), "seed"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", seed=-1), "seed"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", seed=1.5), "seed"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", seed=10**30), "seed"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", realization="a"), "realization"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", replicate=-2), "replicate"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", name=3), "name"),
        ("simulate", lambda: api.simulate("matrix:xu1998_elbow", backend=3), "backend"),
        ("simulate", lambda: api.simulate(3), "config"),
        ("run", lambda: api.run(123), "study"),
        ("run", lambda: api.run(None), "study"),
        ("run", lambda: api.run("xu1998", parts=[3]), "parts"),
        ("run", lambda: api.run("xu1998", out=5), "out"),
        ("run", lambda: api.run("xu1998", executor=5), "executor"),
        ("run", lambda: api.run("xu1998", workers="2"), "workers"),
        ("run", lambda: api.run("xu1998", workers=0), "workers"),
        ("run", lambda: api.run("xu1998", scheduler=5), "scheduler"),
        ("run", lambda: api.run("xu1998", use_cache="no"), "use_cache"),
        ("run", lambda: api.run("xu1998", overrides=[1]), "overrides"),
        ("run", lambda: api.run("xu1998", backend=3), "backend"),
        ("run", lambda: api.run("xu1998", plugins=[None]), "plugins"),
        ("run", lambda: api.run("xu1998", budget="x"), "budget"),
        ("run", lambda: api.run("xu1998", budget=float("nan")), "budget"),
        ("run", lambda: api.run("xu1998", budget=-1), "budget"),
        ("run", lambda: api.run("xu1998", confirm=1), "confirm"),
        ("run", lambda: api.run("xu1998", progress="yes"), "progress"),
        ("run", lambda: api.run("xu1998", record_as=""), "record_as"),
        ("History", lambda: api.History(5), "out"),
        ("History", lambda: h.checks(10**30), "run_id"),
        ("History", lambda: h.run(0), "run_id"),
        ("History", lambda: h.rows("1"), "run_id"),
        ("History", lambda: h.cases(1.0), "run_id"),
        ("History", lambda: h.runs(limit="x"), "limit"),
        ("History", lambda: h.runs(limit=10**30), "limit"),
        ("History", lambda: h.runs(study=3), "study"),
        ("History", lambda: h.runs(kind=3), "kind"),
        ("History", lambda: h.diff(1, -1), "after"),
        ("History", lambda: h.diff(1, 2, config=5), "config"),
        ("fetch_data", lambda: api.fetch_data(5), "name"),
        ("fetch_data", lambda: api.fetch_data("nope"), "name"),
        ("fetch_data", lambda: api.fetch_data("reklab", url=3), "url"),
        ("fetch_data", lambda: api.fetch_data("reklab", folder=3), "folder"),
        ("StudyResult", None, None),                     # a result, built by run
    ]


def test_every_public_function_refuses_wrong_arguments_in_one_line_naming_them(record, tmp_path, monkeypatch):
    """Nothing runs with a wrong argument (the history folder stays empty, no study runs: the current folder
    is an empty one); each is a ConfigError of one line that starts with the argument's name."""
    monkeypatch.chdir(tmp_path)
    calls = _calls(*record, tmp_path / "history")
    assert {name for name, _, _ in calls} == set(api.__all__), "every public function of jointbench.api is fed"
    for name, call, argument in calls:
        if call is None:
            continue
        with pytest.raises(ConfigError) as exc:
            call()
        msg = str(exc.value)
        assert msg.startswith(f"{argument}: ") and "\n" not in msg, (name, argument, msg)
    assert not any(tmp_path.iterdir()), list(tmp_path.iterdir())


def test_the_command_line_words_the_same_rules_by_its_flags():
    from jointbench.cli.common import budget_minutes, positive_int

    for parse, text, rule in ((positive_int, "0", lambda: arguments.whole(0, "x", minimum=1)),
                              (positive_int, "two", lambda: arguments.whole("two", "x", minimum=1)),
                              (budget_minutes, "nan", lambda: arguments.positive("nan", "x", "min"))):
        with pytest.raises(ConfigError) as want:
            rule()
        with pytest.raises(Exception) as got:               # argparse.ArgumentTypeError: argparse adds the flag
            parse(text)
        assert str(got.value) == str(want.value).split(": ", 1)[1]
    assert positive_int("3") == 3 and budget_minutes("2 h") == 120.0


@pytest.mark.parametrize("fs, words", [("0", "--fs: expected a rate > 0 Hz, got '0'"),
                                       ("nan", "--fs: expected a rate > 0 Hz, got 'nan'"),
                                       ("100 s", "--fs: expected a rate > 0 Hz, got '100 s'")])
def test_the_command_line_hands_the_text_to_the_api_which_decides(tmp_path, record, fs, words):
    """``--fs`` is parsed as text and decided by the API's rule (worded by the flag): one rule, one message."""
    from tests.harness_studies import cli_here

    angle, torque = record
    path = tmp_path / "rec.csv"
    pd.DataFrame({"angle": angle, "torque": torque}).to_csv(path, index=False)
    r = cli_here("estimate", "-e", "irf2_ls", "-i", path, "--fs", fs, "-o", tmp_path / "fit.csv")
    assert r.returncode == 2 and r.stderr == f"jointbench: error: {words}\n", r.stderr
    ok = cli_here("estimate", "-e", "irf2_ls", "-i", path, "--fs", "1 kHz", "-o", tmp_path / "fit.csv")
    assert ok.returncode == 0 and (tmp_path / "fit.csv").is_file(), ok.stderr


@pytest.mark.parametrize("given", [1000, 1000.0, np.float32(1000), np.int64(1000), "1000", "1000 Hz", "1 kHz"])
def test_a_rate_is_accepted_as_a_number_or_with_its_unit(record, given):
    angle, torque = record
    fit = api.fit("irf2_ls", angle=angle, torque=torque, fs=given)
    assert fit.estimate.fs == 1000.0


def test_a_seed_is_a_whole_number_of_any_integer_type():
    a = api.simulate("matrix:xu1998_elbow", seed=3, duration="2 s")
    b = api.simulate("matrix:xu1998_elbow", seed=np.int64(3), duration="2 s")
    np.testing.assert_array_equal(a.torque, b.torque)


def test_one_text_stands_for_a_list_of_one(tmp_path):
    """``parts="fig2"`` is the part fig2 (it used to be the parts 'f', 'i', 'g', '2')."""
    with pytest.raises(ConfigError, match="has no part 'a'"):
        api.run("xu1998", overrides="a.b=1", out=tmp_path)
    with pytest.raises(ConfigError, match="unknown part 'nope'"):
        api.run("xu1998", parts="nope", out=tmp_path)


@pytest.mark.parametrize("which", ["angle", "torque"])
def test_a_complex_record_is_refused_not_cut_to_its_real_part(record, which):
    angle, torque = record
    arrays = {"angle": angle, "torque": torque}
    arrays[which] = arrays[which] * (1 + 0.5j)
    with pytest.raises(InputError, match=f"'{which}' is complex"):
        api.fit("irf2_ls", **arrays, fs=100)
    with pytest.raises(InputError, match=f"'{which}' is complex"):
        Trial.from_arrays(arrays["angle"], arrays["torque"], 100.0)


# ------------------------------------------------------------------------------ 5. hostile strings
HOSTILE = ["<!--<script", "</script><script>alert(1)</script>", "]]><!--", "a&amp;b", "\u2028x\u2029",
           "<b>bold</b>", "x\"y'z"]
UNSAFE_LINKS = ["javascript:alert(1)", "JaVaScRiPt:alert(1)", " javascript:alert(1)", "java\tscript:alert(1)",
                "java\nscript:x", "data:text/html,<script>alert(1)</script>", "vbscript:msgbox(1)", "\x01javascript:x"]
SAFE_LINKS = ["https://doi.org/10.1109/x", "http://example.org", "mailto:a@b.org", "report.html", "../a/b.md",
              "#checks", "x.png?a=b"]


def test_script_json_round_trips_and_never_ends_or_opens_a_block():
    from jointbench.benchmarks.harness.pages import script_json

    data = {"strings": HOSTILE, "nested": {s: [s] for s in HOSTILE}}
    text = str(script_json(data))
    assert not set("<>&\u2028\u2029") & set(text)
    assert json.loads(text) == data
    with pytest.raises(ValueError):
        script_json({"x": float("nan")})


def test_links_render_only_with_safe_schemes():
    from jointbench.benchmarks.harness.pages import inline_html

    for href in UNSAFE_LINKS:
        html = str(inline_html(f"see [x]({href}) here"))
        assert "<a " not in html and html.startswith("see ") and html.endswith(" here"), (href, html)
    for href in SAFE_LINKS:
        html = str(inline_html(f"see [x]({href}) here"))
        assert re.search(r'<a href="[^"]+">x</a>', html), (href, html)


def test_a_report_page_has_no_live_unsafe_link(tmp_path):
    from jointbench.benchmarks.harness.pages import (Cell, Items, Page, Paragraph, Section, Table, to_html,
                                                     to_markdown)

    bad = "[x](javascript:alert(1))"
    page = Page("study " + HOSTILE[1], [Section(bad, [Paragraph(f"a reading {bad}"), Items([bad, HOSTILE[0]]),
                                                      Table(bad, [bad], [[Cell(bad)]], note=bad)])])
    page.links = [("javascript:alert(1)", "home")]
    html = to_html(page)
    assert not re.search(r"href=\"\s*javascript", html, re.I) and "<script>alert" not in html
    assert "javascript:alert(1)" in to_markdown(page)             # the markdown keeps the text as written


def _hostile_comparison(tmp_path):
    from jointbench.benchmarks.compare import figures as compare
    from tests.test_comparison_report import synthetic_rows

    rows, curves = synthetic_rows(R=4)
    name = "wr<!--<script>ist</script>"
    for frame in (rows, curves):
        if "scenario" in frame:
            frame["scenario"] = frame["scenario"].replace("wrist", name)
        frame["case_id"] = frame["case_id"].str.replace("wrist", name)
    rows["settings"] = rows["settings"].where(rows["settings"].isna() | (rows["settings"] == ""),
                                              '{"note": "[x](javascript:alert(1))"}')
    rows.loc[rows["estimator"] == "fast", "estimator"] = "fa<!--<script"
    curves.loc[curves["estimator"] == "fast", "estimator"] = "fa<!--<script"
    folder = tmp_path / "matrix"
    folder.mkdir()
    compare.compare_figures(types.SimpleNamespace(name="matrix"), rows, curves, folder, None)
    return folder / "matrix_comparison.html", pd.read_csv(folder / "matrix_scores.csv")


def test_the_comparison_page_keeps_hostile_names_as_data(tmp_path):
    path, table = _hostile_comparison(tmp_path)
    text = path.read_text()
    blob = re.search(r'<script type="application/json" id="data">(.*?)</script>', text, re.S)[1]
    data = json.loads(blob)
    assert len(data["rows"]) == len(table) and any("<!--<script" in s for s in data["strings"])
    assert "<!--" not in blob and not re.search(r"href=\"\s*javascript", text, re.I)


def test_the_comparison_page_with_hostile_names_shows_every_row_in_chromium(tmp_path, chromium):  # noqa: F811
    path, table = _hostile_comparison(tmp_path)
    dom = _browser(chromium, tmp_path / "p", "--virtual-time-budget=10000", "--dump-dom",
                   path.as_uri() + "#metric=vaf_stiffness&backend=analytic")
    assert dom.returncode == 0, dom.stderr
    m = re.search(r'<body[^>]*data-rows="(\d+)"[^>]*data-plots="(\d+)"', dom.stdout)
    want = table[(table["metric"] == "vaf_stiffness") & (table["backend"] == "analytic")]
    assert m and int(m[1]) == len(want) > 3 and int(m[2]) > 0, (m and m.groups(), len(want))
    assert "javascript:" not in "".join(re.findall(r'href="([^"]*)"', dom.stdout)).lower()


# ---------------------------------------------------------------- 7. configuration with no effect
@pytest.mark.parametrize("schedule", ["force", "angle"])
def test_slow_cutoff_with_a_schedule_it_does_not_apply_to_is_refused(tmp_path, schedule, record):
    angle, torque = record
    with pytest.raises(ConfigError, match=rf"slow_cutoff = 2 Hz has no effect with schedule '{schedule}'"):
        estimators.make("pv_irf", {"schedule": schedule, "slow_cutoff": "2 Hz"})
    with pytest.raises(ConfigError, match="slow_cutoff = 2 Hz has no effect"):
        api.fit("pv_irf", angle=angle, torque=torque, fs=100, schedule=schedule, settings={"slow_cutoff": 2})
    assert estimators.make("pv_irf", {"slow_cutoff": 2}).settings.slow_cutoff == 2.0
    assert estimators.make("pv_irf", {"schedule": schedule}).settings.schedule == schedule


def _grid_study(tmp_path, edit):
    from tests.harness_studies import tiny_grid_part, tiny_study

    part = tiny_grid_part(["ibk_spectral", "sds"])
    edit(part)
    return tiny_study(tmp_path / "cfg", extra_parts={"grid": part})


@pytest.mark.parametrize("where", ["part", "scenario"])
def test_a_tuning_search_for_an_estimator_not_on_the_grid_is_refused(tmp_path, where):
    from jointbench.benchmarks.config import load_study

    def edit(part):
        part["grid"]["tuning"] = ["paper", "tuned"]
        search = {"kbr": {"lag_before": ["10 ms", "20 ms"]}}
        (part if where == "part" else part["scenarios"]["elbow"])["tuning"] = search
    with pytest.raises(ConfigError, match=r"tuning: 'kbr' is not on the grid's estimator axis \(ibk_spectral, sds\)"):
        load_study(_grid_study(tmp_path, edit))


def test_a_grid_narrowed_by_set_keeps_its_other_searches_idle_without_error(tmp_path):
    """``--set`` narrowing the estimator or tuning axis of a grid whose searches name the others (the matrix's
    ``--set matrix.grid.estimator=[sds]``) is a choice, not a config with no effect."""
    from jointbench.benchmarks.config import load_study

    def edit(part):
        part["grid"]["tuning"] = ["paper", "tuned"]
        part["tuning"] = {"sds": {"window": ["0.5 s", "1 s"]}}
    path = _grid_study(tmp_path, edit)
    for narrowed, axis, values in (("grid.grid.estimator=[ibk_spectral]", "estimator", ("ibk_spectral",)),
                                   ("grid.grid.tuning=[paper]", "tuning", ("paper",))):
        grid = load_study(path, overrides=[narrowed]).parts["grid"].grid
        assert grid.axes[axis] == values and list(grid.search) == ["sds"]


def test_a_tuning_search_without_a_tuned_column_is_refused(tmp_path):
    from jointbench.benchmarks.config import load_study

    def edit(part):
        part["tuning"] = {"sds": {"window": ["0.5 s", "1 s"]}}
    with pytest.raises(ConfigError, match=r"a search, but the grid's tuning axis has no 'tuned' column"):
        load_study(_grid_study(tmp_path, edit))


def test_a_grid_whose_every_combination_is_skipped_is_an_error_with_the_reasons(tmp_path):
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.runner import expand_study
    from tests.harness_studies import cli

    def edit(part):
        part["only"] = [{"keep": {"noise": [0.5]}, "reason": "only the loud ones"}]
    path = _grid_study(tmp_path, edit)
    with pytest.raises(ConfigError) as exc:
        expand_study(load_study(path), ["grid"])
    msg = str(exc.value)
    assert "nothing to run: every one of the 4 combinations is skipped: 4 x only the loud ones" in msg, msg
    r = cli("run", path, "--parts", "grid", "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "4 x only the loud ones" in r.stderr, r.stderr


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("n", [500, 20_000])
def test_a_schedule_of_noise_is_refused_and_a_moving_one_kept(seed, n):
    from jointbench.fitting.schedule import check_span

    rng = np.random.default_rng(seed)
    noise = 0.003 * rng.standard_normal(n)                      # a few mrad of sensor noise
    t = np.linspace(0, 1, n)
    with pytest.raises(InputError, match="does not move"):
        check_span(0.2 + noise, "'theta'")                     # noise about an offset: relative span ~100 %
    with pytest.raises(InputError, match="does not move"):
        check_span(0.2 + noise + 0.002 * np.sin(2 * np.pi * t), "'theta'")   # a drift within the noise
    check_span(0.2 + noise + 0.3 * np.sin(2 * np.pi * t), "'theta'")       # a movement: 100 x the noise
    check_span(np.round(0.3 * np.sin(2 * np.pi * t), 2), "'theta'")        # quantised, noiseless


def test_a_recorded_schedule_of_noise_is_refused_through_the_api_and_the_command(tmp_path):
    from tests.harness_studies import cli_here

    rng = np.random.default_rng(1)
    n, fs = 4000, 200.0
    angle = 0.02 * rng.standard_normal(n)
    df = pd.DataFrame({"time": np.arange(n) / fs, "angle": angle, "torque": 40 * angle,
                       "theta": 0.1 + 0.002 * rng.standard_normal(n)})
    path = tmp_path / "rec.csv"
    df.to_csv(path, index=False)
    with pytest.raises(InputError, match=r"^schedule: 'theta' in .*rec.csv spans .* it does not move"):
        api.fit("pv_irf", str(path), schedule="theta")
    r = cli_here("estimate", "-e", "pv_irf", "-i", path, "--schedule", "theta", "-o", tmp_path / "fit.csv")
    assert r.returncode == 2 and "--schedule: 'theta'" in r.stderr and "does not move" in r.stderr, r.stderr
    assert not (tmp_path / "fit.csv").exists()
