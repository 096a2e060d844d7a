"""Issue 35, van de Ruit Table I and II checks: a gap-check set fixed by the printed table alone (the generator
reads no result), notes that name reproduced figures by placeholder only, the one-sided noise-free sine."""
from __future__ import annotations

import ast
import importlib.util
import math
import re
import string
from decimal import Decimal

import pytest
import yaml

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.locate import STUDIES

GENERATOR = STUDIES / "vanderuit2018_table1" / "generate_checks.py"
NOTES = ("if_missed", "if_missed_below", "if_missed_above")


@pytest.fixture(scope="module")
def gen():
    spec = importlib.util.spec_from_file_location("vdr_generate_i35", GENERATOR)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_gap_check_generator_has_no_input_from_results(gen):
    """Its only file is the YAML it rewrites; no table of a run, no seed spread, no command-line input."""
    tree = ast.parse(GENERATOR.read_text())
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} | \
        {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert not names & {"read_csv", "read_parquet", "argparse", "ArgumentParser", "argv", "open", "spreads",
                        "SPREAD", "environ"}
    notes = "jointbench.benchmarks.studies.vanderuit2018_table1.notes_text"    # its note texts, beside it
    imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names} | \
        {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module != notes}
    assert imported <= {"__future__", "json", "math", "decimal", "pathlib"}, imported
    texts_tree = ast.parse((GENERATOR.parent / "notes_text.py").read_text())
    assert not [n for n in ast.walk(texts_tree) if isinstance(n, (ast.Import, ast.ImportFrom, ast.Call))]
    docs = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr)}       # docstrings may name them
    texts = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
             and id(n) not in docs]
    assert not [t for t in texts if re.search(r"cases\.(csv|parquet)|checks\.csv|results/", t)]
    reads = [n for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr in ("read_text", "read_bytes")]
    assert len(reads) == 1                     # rewrite(): the YAML whose block it replaces


def test_gaps_checked_are_those_the_printed_digits_resolve(gen):
    """Every published gap larger than the printed rounding of its two cells, computed here from the table in
    decimal; Sec. IV-F's 'VAF_val is higher and RMSE_k lower for the KBR method in presence of noise' is checked
    in every noisy cell."""
    ids = {c.id for c in load_study("vanderuit2018_table1").checks}
    checked = set()
    for (var, method, snr), cells in gen.TABLE1.items():
        if method != "kbr":
            continue
        for col, k, s in zip(gen.COLUMNS, cells, gen.TABLE1[(var, "skirt", snr)]):
            if k is None:
                continue
            gap = Decimal(str(k)) - Decimal(str(s))
            half = {"rmse_k": Decimal("0.005")}.get(col, Decimal("0.05"))
            if abs(gap) > 2 * half:
                checked.add((var, snr, col))
                assert {f"D-{var}-{snr}-{col}-sign", f"D-{var}-{snr}-{col}-size"} <= ids
            else:
                assert f"D-{var}-{snr}-{col}-sign" not in ids
    noisy = {(v, snr, c) for v in gen.VARIATIONS for snr in ("5", "10") for c in ("rmse_k", "vaf_val")}
    assert noisy <= checked and len(checked) == 36


def test_noise_free_sine_vaf_self_is_a_lower_bound_and_the_squares_two_sided():
    checks = {c.id: c for c in load_study("vanderuit2018_table1").checks}
    for method in ("kbr", "skirt"):
        sine = checks[f"T1-sine20-{method}-inf-vaf_self"]
        assert sine.high == 100.0 and sine.low == pytest.approx(100 - (0.1 + 0.05) * 3)
        assert "R14" in sine.tolerance_reason
        for var in ("square10", "square20", "square30"):
            assert checks[f"T1-{var}-{method}-inf-vaf_self"].high < 100.0


def test_per_cell_bands_that_hold_the_other_methods_cell(gen):
    """The cells whose band holds the other method's published cell (these cannot tell the methods apart by the
    paper's own numbers; none is argued otherwise: no spread is printed)."""
    kbr = [(v, s, c) for v in gen.VARIATIONS for s in gen.SNRS for c in ("vaf_self", "rmse_k")
           if (s == "inf" or c == "rmse_k") and gen.holds_other_cell(v, "kbr", s, c)]
    assert ("sine20", "5", "rmse_k") not in kbr and ("sine20", "10", "rmse_k") in kbr
    assert len(kbr) == 9


def _placeholders(text: str):
    for _, field, spec, _ in string.Formatter().parse(text):
        if field is not None:
            yield field, spec


@pytest.mark.parametrize("study", ["vanderuit2018_table1", "vanderuit2018_table2"])
def test_notes_name_reproduced_figures_by_placeholders_that_exist(study):
    """A note's placeholder names a check of the study (its value or its published value) or the check itself,
    and formats a number; the skirt's notes no longer carry N_p = 7's '400 parameters' or 'about half'."""
    raw = yaml.safe_load((STUDIES / study / "published.yaml").read_text())["checks"]
    ids = {c["id"] for c in raw}
    n = 0
    for c in raw:
        for key in NOTES:
            text = c.get(key) or ""
            assert "about half" not in text and "400" not in text, (c["id"], key)
            for field, spec in _placeholders(text):
                name, _, attr = field.partition(".")
                assert name in ids | {"value", "published"} and attr in ("", "published"), (c["id"], field)
                format(1.2345, spec)
                n += 1
    assert n > 0 or study == "vanderuit2018_table2"


def test_table2_kbr_vaf_val_restates_the_calibration():
    checks = {c.id: c for c in load_study("vanderuit2018_table2").checks}
    for cid in ("T2-kbr-single-vaf_val", "T2-kbr-ensemble-vaf_val", "V1-kbr-single-vaf_val-above-70"):
        assert checks[cid].evidence == "calibrated" and "noise" in checks[cid].free_parameter
    assert not math.isinf(checks["A2-guarin-about-sds"].low)
