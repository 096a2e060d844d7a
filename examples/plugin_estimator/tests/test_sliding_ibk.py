"""The plugin's own tests: JointBench's conformance kit on ``sliding_ibk``.

``check_estimator`` fits records of the estimator's own kind (simulated) through the same path as ``jointbench
estimate`` and runs every check (blind fitting, settings, data kinds, degenerate inputs, the output gate, torque
scale, time shift, units, interval coverage, the narrow-band record over a grid of window settings); a failure
names the check, the setting and the input. Run them with ``pytest examples/plugin_estimator/tests`` (the
plugin installed, or imported from its folder here); the repository's tests/test_conformance.py runs them too.
"""
from pathlib import Path

from jointbench.core import plugins
from jointbench.testing import check_estimator

PACKAGE = Path(__file__).resolve().parents[1] / "sliding_ibk"


def load_plugin() -> None:
    """The plugin, installed (its entry point) or from its folder."""
    try:
        import sliding_ibk  # noqa: F401
    except ModuleNotFoundError:
        plugins.load(str(PACKAGE), where="examples/plugin_estimator/tests")


def test_conformance():
    load_plugin()
    print(check_estimator("sliding_ibk"))
