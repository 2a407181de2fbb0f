"""Per-process caches of products that are expensive to make and never change.

:class:`BoundedCache` is a least-recently-used map with a size bound and a lock: a
design sweep over many robots evicts the oldest products instead of growing without
end, and two threads asking for the same product build it once.  ``PRODUCTS`` holds the
robot's derived products (URDF texts, parsed Pinocchio models, CasADi models, compiled
libraries, atlas grids), keyed by (kind, robot hash); :func:`cached` reads it.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any, Generic, TypeVar

from sixplus3.errors import InputError

V = TypeVar("V")


class BoundedCache(Generic[V]):
    """A thread-safe LRU map of at most ``size`` entries.

    :meth:`get` builds a missing entry with ``make()`` while holding the lock (re-entrant:
    a ``make`` may read the same cache), so that a product is built once per process.
    """

    def __init__(self, size: int) -> None:
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise InputError(f"cache size must be a positive integer, got {size!r}",
                             value=size, valid=">= 1")
        self.size = size
        self._items: OrderedDict[Hashable, V] = OrderedDict()
        self._lock = threading.RLock()

    def get(self, key: Hashable, make: Callable[[], V]) -> V:
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
            value = make()
            self._items[key] = value
            while len(self._items) > self.size:
                self._items.popitem(last=False)
            return value

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._items

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def clear(self) -> None:
        with self._lock:
            self._items.clear()


#: Products kept per process (a design sweep over many robots evicts the least recently
#: used).
PRODUCTS: BoundedCache[Any] = BoundedCache(64)


def cached(key: tuple[str, str], make: Callable[[], V]) -> V:
    """The product ``key`` = (kind, robot hash) from :data:`PRODUCTS`, made on first use."""
    return PRODUCTS.get(key, make)  # type: ignore[no-any-return]


__all__ = ["PRODUCTS", "BoundedCache", "cached"]
