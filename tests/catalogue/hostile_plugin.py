"""A plugin estimator that misbehaves on purpose (tests/test_catalogue_harness.py): per its ``mode``
setting it sleeps forever, calls ``sys.exit``, ends its process with ``os._exit(0)``, or fits as
``ibk_spectral`` does (``ok``)."""
from __future__ import annotations

import dataclasses
import os
import sys
import time

from jointbench.core.schema import param
from jointbench.estimators import Estimator, make, register


@register("hostile_test", tags=("plugin",))
class Hostile(Estimator):
    """Misbehaves per ``mode`` (a test plugin)."""

    accepts = frozenset({"trial"})

    @dataclasses.dataclass(frozen=True)
    class Settings:
        mode: str = param("ok", doc="ok, sleep, exit or os_exit")

    def _fit(self, trials):
        mode = self.settings.mode
        if mode == "sleep":
            while True:
                time.sleep(3600)
        if mode == "exit":
            sys.exit(3)
        if mode == "os_exit":
            os._exit(0)
        est = make("ibk_spectral", {"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s", "overlap": 0.5})
        out = est.fit(trials)
        return dataclasses.replace(out, estimator=self.name)
