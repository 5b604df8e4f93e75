"""Work done once for threads that all need it: the first caller of a key computes it, the others
wait for that result (the colour check builds and trains a fold's rows side by side, and an
augmented row needs the synthetic set and network its synthetic row makes)."""

from __future__ import annotations

import threading
from concurrent.futures import Future
from typing import Callable, Hashable


class Once:
    """{key: value} filled by `get(key, make)`: `make()` runs once per key, in the first caller's
    thread; later callers (any thread) get its value, or its exception raised again."""

    def __init__(self):
        self._lock = threading.Lock()
        self._futures: dict = {}

    def get(self, key: Hashable, make: Callable[[], object]):
        with self._lock:
            future = self._futures.get(key)
            mine = future is None
            if mine:
                future = self._futures[key] = Future()
        if mine:
            try:
                future.set_result(make())
            except BaseException as error:
                future.set_exception(error)
        return future.result()
