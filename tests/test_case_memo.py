"""Parsed inputs shared by the cases of a group (benchmarks.harness.case.parse_inputs with a memo)."""
import numpy as np

from jointbench.benchmarks.harness import case as case_mod
from jointbench.benchmarks.harness.case import Case, _plain, parse_inputs


def _case(seed=0, **kw) -> Case:
    spec = dict(study="s", part="p", protocol="parametric_fit", params={}, sweep={},
                experiment={"joint": {"model": "second_order", "I": 0.01, "B": 0.5, "K": 50},
                            "perturbation": {"kind": "filtered_noise", "cutoff": "20 Hz", "rms": "0.02 rad"},
                            "fs_sim": "1 kHz", "duration": "2 s"},
                estimators={"ibk_spectral": {"segment": "1 s"}}, seed=seed, where="s.yaml: parts.p")
    spec.update(kw)
    return Case(**spec)


def test_plain_keys_tell_every_value_apart_and_refuse_other_objects():
    assert _plain({"a": 1}) == _plain({"a": 1})
    assert len({_plain(v) for v in (1, 1.0, True, "1", [1], (1,), {"k": 1}, None)}) == 8
    assert _plain({"a": [1, {"b": 2.5}]}) != _plain({"a": [1, {"b": 2.25}]})
    assert _plain(np.zeros(3)) is None and _plain({"a": [{1, 2}]}) is None and _plain(object()) is None
    assert _plain(np.float64(1.5)) != _plain(1.5)        # a float subclass: exact, and kept apart by its type
    assert _plain({1.5: "x"}) is not None and _plain({(1, 2): "x"}) is None


def test_a_group_parses_equal_inputs_once_and_each_case_gets_its_own_estimator(monkeypatch):
    calls = []
    real = case_mod.parse

    def counting(cls, data, where):
        calls.append(cls.__name__)
        return real(cls, data, where)

    monkeypatch.setattr(case_mod, "parse", counting)
    memo = {}
    a = parse_inputs(_case(seed=0), memo)
    b = parse_inputs(_case(seed=1), memo)
    assert calls == [a[1].__class__.__name__]            # the params once (experiment and settings: own parsers)
    assert a[1] is b[1] and a[2] is b[2]                 # the same frozen parameters and experiment
    assert a[3]["ibk_spectral"] is not b[3]["ibk_spectral"]
    assert a[3]["ibk_spectral"].settings is b[3]["ibk_spectral"].settings
    c = parse_inputs(_case(seed=0, estimators={"ibk_spectral": {"segment": "0.5 s"}}), memo)
    assert c[3]["ibk_spectral"].settings.segment == 0.5 and a[3]["ibk_spectral"].settings.segment == 1.0
    assert c[2] is a[2]
    fresh = parse_inputs(_case(seed=0))                  # without a memo: parsed anew, equal
    assert fresh[2] == a[2] and fresh[2] is not a[2] and fresh[1] == a[1]
