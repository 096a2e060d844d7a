"""Reuse of simulated responses: trials that differ only in their sensors, noise or acquisition share one.

:func:`sims.simulate` splits into two halves. The first (the perturbation, the voluntary torque and the
backend's response of the limb and apparatus, at the simulation rate) depends only on the experiment's
joint, apparatus, perturbation, voluntary torque, gravity, rate, length and backend, and on the seed's
perturbation and voluntary streams (and the realization). The second (sensor filters, noise, quantization,
acquisition and the truth) is cheap and depends on the rest. Trials that differ only in the second half
(another noise level, a replicate with a new noise draw, another acquired rate, the same trial fitted by
another estimator) can reuse the first.

Inside ``with reuse_responses():`` every :func:`sims.simulate` call looks its first half up by
:func:`response_key` and computes it only when it is new; outside such a block nothing is kept. A whole trial asked for
again (the same experiment, seed, replicate and realization: one trial fitted by several estimators) is
kept too. What a block keeps is handed out as the same arrays, read-only (``writeable`` off, in fresh containers:
copying them was a tenth of xu1998's simulation, issue 22), so a reused trial is bit-identical to one computed
alone and no caller can change what the memo keeps (an in-place change raises ``ValueError: assignment destination
is read-only``; tests/test_reuse.py). The block is what a harness opens around a group of cases scheduled together.
"""
from __future__ import annotations

import collections
import dataclasses
import pickle
from typing import Any, Callable

import numpy as np

#: the fields of an Experiment that decide its response (everything but sensors, acquisition and 'where')
RESPONSE_FIELDS = ("joint", "perturbation", "apparatus", "voluntary", "gravity", "fs_sim", "duration", "reflex",
                   "backend")

_MEMOS: list["ResponseMemo"] = []


def response_key(experiment: Any, seed: Any, realization: int, backend: str) -> bytes | None:
    """Bytes that equal for two simulations exactly when their responses are the same (None: do not reuse).

    The key holds the response fields of the experiment, the backend's name, the seed (its entropy, spawn
    key and children spawned so far: a SeedSequence object given twice spawns other streams the second
    time) and the realization. The replicate is not in
    it: a replicate redraws the noise streams only.
    """
    if not isinstance(backend, str):
        return None                        # a backend object: its identity is not a value
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    try:
        fields = tuple(getattr(experiment, f) for f in RESPONSE_FIELDS[:-1])
        return pickle.dumps((fields, backend, ss.entropy, tuple(ss.spawn_key), ss.n_children_spawned,
                             int(realization)), protocol=4)
    except (pickle.PicklingError, TypeError, AttributeError):
        return None


def _nbytes(value: Any) -> int:
    if isinstance(value, np.ndarray):
        return value.nbytes
    if dataclasses.is_dataclass(value):
        return sum(_nbytes(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    if isinstance(value, (tuple, list)):
        return sum(_nbytes(v) for v in value)
    return 0


def _share(value: Any) -> Any:
    """``value`` in fresh containers (dataclasses, dicts, tuples, lists rebuilt) holding the same arrays, made
    read-only: what the memo keeps can be handed out any number of times and no caller can change it."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
        return value
    if dataclasses.is_dataclass(value):
        return dataclasses.replace(value, **{f.name: _share(getattr(value, f.name)) for f in dataclasses.fields(value)
                                             if f.init})
    if isinstance(value, dict):
        return {k: _share(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(_share(v) for v in value)
    if isinstance(value, list):
        return [_share(v) for v in value]
    return value


class ResponseMemo:
    """The responses computed inside one :func:`reuse_responses` block (least recently used dropped beyond
    ``max_bytes``), with the counts of computed and reused ones."""

    def __init__(self, max_bytes: float = 2e9, enabled: bool = True):
        self.max_bytes, self.enabled = max_bytes, enabled
        self.trials: ResponseMemo | None = None      # whole trials (see reuse_responses)
        self.sensed: ResponseMemo | None = None      # filtered and acquired noise-free channels (lookup_sensed)
        self.noise: ResponseMemo | None = None       # unit sensor noise, raw and acquired (lookup_noise)
        self.entries: collections.OrderedDict[bytes, tuple[Any, int]] = collections.OrderedDict()
        self.size = 0
        self.computed = 0
        self.reused = 0

    def get(self, key: bytes | None, compute: Callable[[], Any]) -> tuple[Any, bool]:
        """``(value, reused)``: the stored value for ``key``, else ``compute()`` (kept when ``key`` is not
        None); a kept value is handed out in fresh containers with read-only arrays (:func:`_share`)."""
        if not self.enabled:
            key = None
        if key is not None and key in self.entries:
            self.entries.move_to_end(key)
            self.reused += 1
            return _share(self.entries[key][0]), True
        value = compute()
        self.computed += 1
        if key is not None:
            n = _nbytes(value)
            value = _share(value)             # kept: read-only from now on, for this caller too
            self.entries[key] = (value, n)
            self.size += n
            while self.size > self.max_bytes and len(self.entries) > 1:
                _, (_, m) = self.entries.popitem(last=False)
                self.size -= m
            return _share(value), False
        return value, False


class reuse_responses:
    """Context manager: inside it, :func:`sims.simulate` computes each distinct response once
    (``enabled=False``: every one anew, even inside an outer block; for tests and measurements).

    ``max_bytes`` bounds the responses and the whole trials (half each); the noise-free sensed channels
    (:func:`lookup_sensed`) and the unit sensor noise (:func:`lookup_noise`) get a quarter each on top, so a
    block keeps at most 1.5 ``max_bytes``.

    >>> with reuse_responses() as memo:      # doctest: +SKIP
    ...     a = simulate(exp_noise_1, 0); b = simulate(exp_noise_2, 0)
    >>> memo.computed, memo.reused
    (1, 1)
    """

    def __init__(self, max_bytes: float = 2e9, enabled: bool = True):
        self.memo = ResponseMemo(max_bytes / 2, enabled)
        self.memo.trials = ResponseMemo(max_bytes / 2, enabled)
        self.memo.sensed = ResponseMemo(max_bytes / 4, enabled)
        self.memo.noise = ResponseMemo(max_bytes / 4, enabled)

    def __enter__(self) -> ResponseMemo:
        _MEMOS.append(self.memo)
        return self.memo

    def __exit__(self, *exc) -> None:
        _MEMOS.remove(self.memo)


def active() -> bool:
    """Whether a :func:`reuse_responses` block is open (in this process)."""
    return bool(_MEMOS)


def lookup(key: bytes | None, compute: Callable[[], Any]) -> tuple[Any, bool]:
    """The innermost open memo's ``get`` (or ``compute()`` when no block is open)."""
    if not _MEMOS:
        return compute(), False
    return _MEMOS[-1].get(key, compute)


def _derived_key(response: bytes | None, parts: tuple) -> bytes | None:
    """A key derived from a response's: the response key followed by the pickled ``parts`` (None when the
    response has no key or a part cannot be pickled: then nothing is kept)."""
    if response is None:
        return None
    try:
        return response + pickle.dumps(parts, protocol=4)
    except (pickle.PicklingError, TypeError, AttributeError):
        return None


def _lookup_in(memo: str, key: bytes | None, compute: Callable[[], Any]) -> tuple[Any, bool]:
    """``get`` of the named secondary memo (``trials``, ``sensed``, ``noise``) of the innermost open block, or
    ``compute()`` when no block is open."""
    inner = getattr(_MEMOS[-1], memo) if _MEMOS else None
    if inner is None:
        return compute(), False
    return inner.get(key, compute)


def trial_key(response: bytes | None, experiment: Any, replicate: int, name: str) -> bytes | None:
    """Key of a whole trial: its response's key with the sensors, the acquisition, the replicate and the
    name (a trial asked for twice, by two cases that fit it with different estimators, is the same)."""
    return _derived_key(response, (experiment.sensors, experiment.acquisition, int(replicate), str(name)))


def lookup_trial(key: bytes | None, compute: Callable[[], Any]) -> tuple[Any, bool]:
    """Like :func:`lookup`, for whole trials (the second memo of the innermost open block)."""
    return _lookup_in("trials", key, compute)


def sensed_key(response: bytes | None, experiment: Any) -> bytes | None:
    """Key of a response's noise-free sensed channels: its response's key with the two sensors' analog
    filters and the acquisition (the noise, its filter and the quantization do not enter)."""
    return _derived_key(response, ("sensed", experiment.sensors.angle.filter, experiment.sensors.torque.filter,
                                   experiment.acquisition))


def lookup_sensed(key: bytes | None, compute: Callable[[], Any]) -> tuple[Any, bool]:
    """Like :func:`lookup`, for the noise-free sensed channels of a response (the third memo of the innermost
    open block): trials that differ only in their noise or quantization filter and acquire them once."""
    return _lookup_in("sensed", key, compute)


def noise_key(response: bytes | None, experiment: Any, stream: str, noise_filter: Any, replicate: int) -> bytes | None:
    """Key of a channel's unit noise (before its gain): the response's key (which holds the seed and the
    realization) with the noise stream, the replicate, the noise filter and the acquisition."""
    return _derived_key(response, ("noise", str(stream), int(replicate), noise_filter, experiment.acquisition))


def lookup_noise(key: bytes | None, compute: Callable[[], Any]) -> tuple[Any, bool]:
    """Like :func:`lookup`, for a channel's unit noise (the fourth memo of the innermost open block): trials
    that differ only in the noise level draw, filter and acquire it once."""
    return _lookup_in("noise", key, compute)
