"""How ``make test`` spreads the tests over its xdist workers (tests/conftest.py): a module is one unit of
work (its module-scoped fixtures made once), but for the modules listed as independent."""
import pytest

from tests.conftest import SPLIT, pytest_xdist_make_scheduler, work_unit


def test_a_module_is_one_unit_with_its_classes_and_parameters():
    assert work_unit("tests/test_wheel.py::test_a[x-1]") == "tests/test_wheel.py"
    assert work_unit("tests/test_wheel.py::Test::test_b") == "tests/test_wheel.py"
    assert work_unit("tests/sub/test_c.py::test_d[a::b]") == "tests/sub/test_c.py"


def test_a_split_module_is_spread_test_by_test():
    assert "tests.test_history" in SPLIT
    node = "tests/test_history.py::test_history_and_diff_commands"
    assert work_unit(node) == node
    assert work_unit("tests/test_history_other.py::test_x") == "tests/test_history_other.py"


def test_the_scheduler_groups_by_unit_under_loadgroup_only():
    pytest.importorskip("xdist")

    class Config:                                    # the two values the hook and xdist's scheduler read
        def __init__(self, dist):
            self.dist = dist

        def getvalue(self, name):
            return {"dist": self.dist, "tx": ["2*popen"], "numprocesses": None}.get(name)

        @property
        def option(self):
            return self

    assert pytest_xdist_make_scheduler(Config("load"), None) is None
    sched = pytest_xdist_make_scheduler(Config("loadgroup"), None)
    assert sched._split_scope("tests/test_wheel.py::test_a[x]") == "tests/test_wheel.py"
    assert sched._split_scope("tests/test_history.py::test_y") == "tests/test_history.py::test_y"


def test_the_units_go_out_in_collection_order_not_largest_first():
    """xdist reorders the units by their number of tests unless told not to: the scheduler keeps the order of
    the collection (conftest's FIRST, the costliest modules first)."""
    pytest.importorskip("xdist")
    from types import SimpleNamespace

    class Config:
        option = SimpleNamespace(loadscopereorder=True)        # xdist's default

        def getvalue(self, name):
            return {"dist": "loadgroup", "tx": ["2*popen"], "numprocesses": None}.get(name)

    class Node:
        def __init__(self, name):
            self.gateway, self.sent, self.shutting_down = SimpleNamespace(id=name), [], False

        def send_runtest_some(self, indexes):
            self.sent.append(indexes)

        def shutdown(self):
            pass

    collection = ["tests/test_plugins.py::test_a", "tests/test_plugins.py::test_b",
                  *[f"tests/test_many.py::test_{i}" for i in range(5)], "tests/test_history.py::test_c"]
    sched = pytest_xdist_make_scheduler(Config(), None)
    nodes = [Node("gw0"), Node("gw1")]
    for node in nodes:
        sched.add_node(node)
        sched.add_node_collection(node, collection)
    sched.schedule()
    assert nodes[0].sent[0] == [0, 1] and nodes[1].sent[0] == [2, 3, 4, 5, 6]    # test_plugins first
