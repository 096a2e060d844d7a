"""One home per shared computation (issue 33): a scan of the source tree fails on a second definition.

The homes (docs/architecture.md, "One home"):

* the VAF: ``jointbench/core/scores.py`` (:func:`jointbench.core.scores.vaf`);
* the confidence level, its quantiles, the segment-robust covariance and the pseudo-inverse of a Gram
  matrix: ``jointbench/core/intervals.py``;
* the coherence threshold, an excited frequency and the input's band: ``jointbench/core/band.py``.

Each rule is a pattern of the syntax tree (not of the text: a comment or a docstring never counts), and
:func:`test_a_planted_copy_is_caught` shows that each one finds a planted copy.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CODE = ("jointbench", "sims", "estimators", "benchmarks")

SCORES, INTERVALS, BAND = "jointbench/core/scores.py", "jointbench/core/intervals.py", "jointbench/core/band.py"

#: (file, function) -> why it is not a second definition. Kept short: every entry is read in review.
ALLOWED = {
    ("benchmarks/metrics.py", "vafm"): "Xu & Hollerbach's VAFM: the mean's error over a floored mean square",
    ("benchmarks/metrics.py", "vafv"): "Xu & Hollerbach's VAFV: its denominator floored at 1 (eq. 8's rule)",
    ("benchmarks/compare/plots.py", "_vaf_text"): "formats a VAF for a label",
    ("estimators/parallel_cascade.py", "_iterate"): "the iteration's stopping VAF from the normal equations' "
                                                    "sums (no prediction is formed)",
}
#: the public functions of the homes: a module-level function of one of these names elsewhere is a copy
HOME_NAMES = {"vaf", "t_quantile", "z_quantile", "segment_covariance", "contrast_dof", "eigen_pinv", "psd_pinv",
              "psd_solve", "coherence_threshold", "significant", "has_power", "powered", "excited", "frf_and_coherence",
              "input_band", "excited_share", "chance"}
#: files whose 0.95 is data (a published value), not the confidence level
DATA_FILES = {"benchmarks/studies/vanderuit2018_table1/generate_checks.py"}


def _is_num(node, *values) -> bool:
    return isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and \
        not isinstance(node.value, bool) and float(node.value) in values


def _called(node) -> str:
    f = node.func if isinstance(node, ast.Call) else None
    return f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""


def _var_call(node) -> bool:
    return isinstance(node, ast.Call) and _called(node) == "var"


def _percent_explained(node) -> bool:
    """``100 * (1 - a / b)`` (either order), or ``1 - var(.) / var(.)``."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        for k, other in ((node.left, node.right), (node.right, node.left)):
            if _is_num(k, 100) and isinstance(other, ast.BinOp) and isinstance(other.op, ast.Sub) and \
                    _is_num(other.left, 1) and isinstance(other.right, ast.BinOp) and \
                    isinstance(other.right.op, ast.Div):
                return True
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Sub) and _is_num(node.left, 1):
        r = node.right
        return isinstance(r, ast.BinOp) and isinstance(r.op, ast.Div) and _var_call(r.left) and _var_call(r.right)
    return False


def _significance(node) -> bool:
    """``c ** (1 / (n - 1))``: the coherence threshold's power."""
    if not (isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow)):
        return False
    e = node.right
    return isinstance(e, ast.BinOp) and isinstance(e.op, ast.Div) and _is_num(e.left, 1) and \
        isinstance(e.right, ast.BinOp) and isinstance(e.right.op, ast.Sub) and _is_num(e.right.right, 1)


def _gram(node) -> bool:
    """``X.T @ X`` (``X`` any expression)."""
    return isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult) and \
        isinstance(node.left, ast.Attribute) and node.left.attr == "T"


def _pinv_of_gram(node) -> bool:
    """``pinv(X.T @ X)``, or the eigen-pseudo-inverse ``(V / w) @ V.T`` / ``V @ ((V.T @ b) / w)``."""
    if isinstance(node, ast.Call) and _called(node) == "pinv" and node.args and _gram(node.args[0]):
        return True
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
        left, right = node.left, node.right
        if isinstance(left, ast.BinOp) and isinstance(left.op, ast.Div) and isinstance(right, ast.Attribute) \
                and right.attr == "T":
            return True
        if isinstance(right, ast.BinOp) and isinstance(right.op, ast.Div) and _gram(right.left):
            return True
    return False


def _functions(tree):
    """(enclosing function name or '', node) for every node."""
    def walk(node, fn):
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else fn
            yield name, child
            yield from walk(child, name)
    yield from walk(tree, "")


def second_homes(files: dict[str, str]) -> list[str]:
    """Every second definition in ``files`` (relative path -> source), one line each."""
    out = []
    for path, source in files.items():
        tree = ast.parse(source)
        for fn, node in _functions(tree):
            allowed = (path, fn) in ALLOWED
            where = f"{path}:{getattr(node, 'lineno', '?')} ({fn or 'module'})"
            if path != SCORES and not allowed and _percent_explained(node):
                out.append(f"{where}: a VAF computed outside {SCORES}")
            if path != INTERVALS and path not in DATA_FILES and (_is_num(node, 0.95, 0.975)):
                out.append(f"{where}: the level {node.value} outside {INTERVALS} (use LEVEL)")
            if path != BAND and _significance(node):
                out.append(f"{where}: the coherence threshold outside {BAND}")
            if path != INTERVALS and _pinv_of_gram(node):
                out.append(f"{where}: a pseudo-inverse of a Gram matrix outside {INTERVALS} (psd_pinv, psd_solve)")
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and path != SCORES and \
                    (path, node.name) not in ALLOWED and "vaf" in node.name.lower():
                calls = {_called(c) for c in ast.walk(node) if isinstance(c, ast.Call)}
                if "vaf" not in calls:
                    out.append(f"{where}: {node.name} is named a VAF but does not call the core's vaf")
    # a function name defined twice among the shared computations' names (the homes' own, and these words)
    homes: dict[str, list[str]] = {}
    for path, source in files.items():
        for node in ast.parse(source).body:
            if isinstance(node, ast.FunctionDef) and (node.name in HOME_NAMES or any(w in node.name for w in (
                    "interval", "vaf", "quantile", "pinv", "covariance", "significan", "coherence"))):
                homes.setdefault(node.name, []).append(path)
    out += [f"{name} is defined in {len(paths)} modules: {', '.join(paths)}"
            for name, paths in homes.items() if len(paths) > 1]
    return out


def tree_sources() -> dict[str, str]:
    return {str(f.relative_to(REPO)): f.read_text() for d in CODE for f in sorted((REPO / d).rglob("*.py"))}


def test_one_home_for_each_shared_computation():
    found = second_homes(tree_sources())
    assert not found, "\n".join(found)


PLANTED = {
    "a VAF": "import numpy as np\ndef score(y, yhat):\n    return 100 * (1 - np.var(y - yhat) / np.var(y))\n",
    "a VAF without 100": "def s(y, e):\n    return 1.0 - y.var() / e.var()\n",
    "a named VAF": "def my_vaf(y, yhat):\n    return 42.0\n",
    "the level": "LEVEL = 0.95\n",
    "the quantile's level": "from scipy import stats\nq = stats.norm.ppf(0.975)\n",
    "the threshold": "def crit(n):\n    return 1 - 0.05 ** (1.0 / (n - 1.0))\n",
    "pinv of a Gram": "import numpy as np\ndef cov(A):\n    return np.linalg.pinv(A.T @ A)\n",
    "an eigen pinv": "def P(V, w, k):\n    return (V[:, k] / w[k]) @ V[:, k].T\n",
    "an eigen solve": "def c(V, b, w):\n    return V @ ((V.T @ b) / w)\n",
}


@pytest.mark.parametrize("what", sorted(PLANTED))
def test_a_planted_copy_is_caught(what):
    """The scan is not vacuous: each planted copy, in a module of its own, is named."""
    found = second_homes({"estimators/planted.py": PLANTED[what]})
    assert found and all("estimators/planted.py" in f for f in found), found


def test_a_function_defined_twice_is_caught():
    src = "def percentile_interval(x):\n    return x\n"
    found = second_homes({"benchmarks/a.py": src, "benchmarks/b.py": src})
    assert any("percentile_interval is defined in 2 modules" in f for f in found)


def test_the_homes_themselves_pass():
    homes = {p: (REPO / p).read_text() for p in (SCORES, INTERVALS, BAND)}
    assert second_homes(homes) == []
