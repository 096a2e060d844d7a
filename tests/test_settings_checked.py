"""Settings are checked on construction as ``make()`` checks them (one mechanism: schema.checked)."""
import dataclasses

import numpy as np
import pytest

from jointbench import estimators
from jointbench.core.errors import ConfigError


def _bounded_fields():
    estimators.import_all()
    for name in estimators.REGISTRY.names():
        cls = estimators.REGISTRY.get(name)
        for f in dataclasses.fields(cls.Settings):
            for bound in ("ge", "gt"):
                b = f.metadata.get(bound)
                if b is not None and f.type in ("float", float):
                    yield name, f.name, float(b) - 1.0
                    break


CASES = list(_bounded_fields())


def test_there_are_bounded_settings_to_try():
    assert len(CASES) >= 20, CASES


@pytest.mark.parametrize("name,key,bad", CASES)
def test_direct_construction_is_refused_like_make(name, key, bad):
    cls = estimators.REGISTRY.get(name)
    with pytest.raises(ConfigError) as made:
        estimators.make(name, {key: bad})
    with pytest.raises(ConfigError) as built:
        cls.Settings(**{key: bad})
    # same check, same words; only the prefix (where the value came from) differs
    assert str(made.value).split(f"key '{key}'", 1)[1] == str(built.value).split(f"key '{key}'", 1)[1]
    assert str(built.value).startswith(f"{cls.Settings.__qualname__}: key '{key}'")


def test_the_issue_example_and_replace_are_checked():
    cls = estimators.REGISTRY.get("irf2_ls")
    with pytest.raises(ConfigError, match=r"lag_before.*>= 0"):
        cls.Settings(lag_before=-5.0)
    s = cls.Settings(lag_before="40 ms")            # units convert as in a config
    assert s.lag_before == pytest.approx(0.04)
    with pytest.raises(ConfigError, match="pseudo_inverse"):
        dataclasses.replace(s, pseudo_inverse="bogus")
    assert cls.Settings(lag_after=np.float64(0.2)).lag_after == 0.2   # numbers computed by code pass
    assert cls.Settings() == estimators.make("irf2_ls").settings


def test_a_subclass_outside_the_repository_is_checked_too():
    from jointbench.core.schema import param

    class Outside(estimators.Estimator):
        @dataclasses.dataclass(frozen=True)
        class Settings:
            width: float = param(1.0, unit="s", gt=0)

        def _fit(self, trials):
            raise NotImplementedError

    with pytest.raises(ConfigError, match="must be > 0"):
        Outside.Settings(width=0.0)
    assert Outside.Settings(width="500 ms").width == 0.5
